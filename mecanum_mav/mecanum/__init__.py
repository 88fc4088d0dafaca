"""The mathematics of a mecanum base: frames and poses, kinematics, mixing, input shaping,
odometry and the speed envelope. Pure functions and small value types; numpy and math only."""
