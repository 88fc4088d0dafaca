"""Parameters, no files, no I/O: the schema as data (``schema``), one entry's type and
value check (``spec``), the cross-parameter rules (``rules``), the validated store
(``params``) and the typed views the control loop reads (``views``)."""
