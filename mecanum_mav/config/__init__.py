"""The one parameter schema and the validated parameter store (no files, no I/O)."""
