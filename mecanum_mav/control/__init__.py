"""The rover's decisions: arming, modes and failsafes, stick input, GUIDED and AUTO, the
estimator, the PWM edge and :class:`~mecanum_mav.control.core.RoverCore`, which ties them
together with messages and time in and messages out."""
