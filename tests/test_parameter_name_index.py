"""The schema's name index (``SPECS``), built from the schema list: each name leads to the
entry of that name, in schema order (the order files and tables list parameters in)."""

from __future__ import annotations

from mecanum_mav.config.schema import SCHEMA, SPECS, _index


def test_the_name_index_maps_each_name_to_its_own_entry_in_schema_order() -> None:
    index = _index(SCHEMA)  # built again here: SPECS was built at import, before any test
    assert list(index) == [spec.name for spec in SCHEMA]
    assert all(index[spec.name] is spec for spec in SCHEMA)
    assert index == SPECS
