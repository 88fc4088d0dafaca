"""``mecanum_mav.params``: the documented import path of the parameter schema and files.

The schema is data in :mod:`mecanum_mav.config.schema` (every parameter's definition), the
cross-parameter rules in :mod:`mecanum_mav.config.rules`, the validated store in
:mod:`mecanum_mav.config.params` (which re-exports the other two), the file format in
:mod:`mecanum_mav.io.paramfile` (see docs/architecture.md); this module re-exports the store's
and the file format's names, so ``from mecanum_mav.params import Params, load, save`` keeps
working.

``python -m mecanum_mav.params --table`` prints the parameter reference table and
``python -m mecanum_mav.params --write-defaults params/default.parm`` regenerates the
defaults file from the schema.
"""

from mecanum_mav.config.params import *  # noqa: F403
from mecanum_mav.config.params import __all__ as _schema_names
from mecanum_mav.io.paramfile import *  # noqa: F403
from mecanum_mav.io.paramfile import __all__ as _file_names
from mecanum_mav.io.paramfile import main as _main

__all__ = [*_schema_names, *_file_names]

if __name__ == "__main__":
    raise SystemExit(_main())
