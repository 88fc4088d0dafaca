"""The simulator: the chassis, a simulated ArduPilot Rover board (on a socket or in virtual
time) and the lockstep harness with its scripted ground station."""
