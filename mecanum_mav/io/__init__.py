"""Sockets and files: MAVLink links, atomic writes, parameter and mission file formats."""
