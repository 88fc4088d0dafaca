"""MAVLink without sockets: the dialect, the fast codec of the control path, RC override
rules, mode numbers, status texts, telemetry messages, and the parameter and mission services."""
