"""The companion's loop, in one place: the shell (:mod:`mecanum_mav.app.companion`) runs it on
real links and epoll, the lockstep harness (:mod:`mecanum_mav.sim.lockstep`) steps it on
virtual links in virtual time (see :mod:`mecanum_mav.runtime.loop`).

Its layer sits above control and io (it drives the core with the links) and below sim and app.
"""

from mecanum_mav.runtime.loop import ControlLoop, LoopLink, LoopPoller, link_counts

__all__ = ["ControlLoop", "LoopLink", "LoopPoller", "link_counts"]
