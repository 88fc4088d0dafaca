"""The Rerun view's layout (:func:`blueprint`), its application id and timeline, and ``rerun``
imported on demand (:func:`rerun_module`: the ``view`` extra is optional). What is drawn:
:mod:`~mecanum_mav.app.rerunview`."""

from __future__ import annotations

from typing import Any

__all__ = ["APPLICATION_ID", "TIMELINE", "blueprint", "rerun_module"]

APPLICATION_ID = "mecanum-mav"
"""The Rerun application id of every recording."""
TIMELINE = "time"
"""The one timeline: Unix time (a tlog record's stamp, or the receive time live)."""


def rerun_module() -> Any:
    """``rerun``, imported now; RuntimeError with the install hint when the ``view`` extra is
    missing."""
    try:
        import rerun
    except ImportError as exc:
        raise RuntimeError("the view needs rerun-sdk: pip install 'mecanum-mav[view]'") from exc
    return rerun


def blueprint() -> Any:
    """The view's layout: the map (whole past: the paths build up to the time cursor) and the
    chassis close up on the left; sticks, wheel commands, PWM, speed and cross-track, the
    mode and arming states and the events on the right."""
    rerun_module()
    import rerun.blueprint as rrb

    whole_past = rrb.VisibleTimeRange(
        TIMELINE, start=rrb.TimeRangeBoundary.infinite(),
        end=rrb.TimeRangeBoundary.cursor_relative())
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                rrb.Spatial2DView(name="map (east right, north up; m)", origin="/map",
                                  contents=["$origin/**", "- /map/rover/wheels",
                                            "- /map/rover/slip"],
                                  time_ranges=[whole_past]),
                rrb.Spatial2DView(name="chassis and wheel commands (nose up)",
                                  origin="/map/rover"),
                row_shares=[3, 1]),
            rrb.Vertical(
                rrb.TimeSeriesView(name="sticks (-1..1)", origin="/sticks"),
                rrb.TimeSeriesView(name="wheel commands (-1..1)", origin="/wheels/command"),
                rrb.TimeSeriesView(name="wheel PWM (us)", origin="/wheels/pwm"),
                rrb.TimeSeriesView(name="wheel contact normal force (N)",
                                   origin="/contacts/normal"),
                rrb.TimeSeriesView(name="speed (m/s) and cross-track (m)",
                                   contents=["/speed/**", "/track/**"]),
                rrb.StateTimelineView(name="mode and arming", origin="/state"),
                rrb.TextLogView(name="events", origin="/events"),
            ),
            column_shares=[1, 1]),
        collapse_panels=True)
