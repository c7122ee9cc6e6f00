"""``uavlink plot FLIGHT.tlog``: the flight picture (or its animation) from a telemetry log alone,
and the picture ``uavlink fly`` draws after every flight. Both read the log with
:func:`~uavlink.plot.tlog.read_flight` and draw with
:func:`~uavlink.plot.picture.draw_flight`, so they draw the same picture.

pymavlink and matplotlib are imported when a picture is drawn; the command's options are
``uavlink.cli.plot``'s.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING

from uavlink.errors import UserError

if TYPE_CHECKING:
    from uavlink.plot.animation import AnimationInfo
    from uavlink.plot.picture import PictureInfo


def render(tlog: Path, out: Path, gif: bool = False, title: str | None = None) -> dict:
    """Read ``tlog`` and write its picture (or animation) to ``out`` through a temporary file (an
    error leaves nothing half-written); what was drawn, as a dict. UserError for an unusable log,
    a missing matplotlib or an unwritable ``out``."""
    from uavlink.plot.picture import PlotUnavailable
    from uavlink.plot.tlog import read_flight

    data = read_flight(tlog)
    out.parent.mkdir(parents=True, exist_ok=True)
    partial = out.with_name(f".{out.name}.partial{out.suffix}")
    info: AnimationInfo | PictureInfo
    try:
        if gif:
            from uavlink.plot.animation import animate_flight

            info = animate_flight(data, partial, title)
        else:
            from uavlink.plot.picture import draw_flight

            info = draw_flight(data, partial, title)
        os.replace(partial, out)
    except PlotUnavailable as exc:
        raise UserError(str(exc)) from None
    except OSError as exc:
        raise UserError(f"cannot write {out}: {exc.strerror or exc}") from None
    finally:
        partial.unlink(missing_ok=True)
    drawn = {k: (str(out) if k == "path" else v) for k, v in asdict(info).items()}
    return {**drawn, "notes": data.notes}


def picture_after_flight(tlog: Path, out: Path) -> dict:
    """``uavlink fly``'s picture: ``{"picture": path, "picture_s": seconds}``, or
    ``{"picture": None, "picture_skipped": why}`` when it cannot be drawn; a flight never fails for
    its picture."""
    started = time.perf_counter()
    try:
        render(tlog, out)
    except UserError as exc:
        return {"picture": None, "picture_skipped": str(exc)}
    return {"picture": str(out), "picture_s": round(time.perf_counter() - started, 3)}


def run_plot(
    tlog: Path,
    out: Path | None = None,
    gif: bool = False,
    title: str | None = None,
    as_json: bool = False,
) -> int:
    """``uavlink plot``: draw ``tlog``'s flight to ``out`` (PNG, or an animated GIF) and say what
    was drawn; its exit status."""
    if tlog.is_dir():
        raise UserError(f"{tlog} is a folder; give a telemetry log (FLIGHT.tlog)")
    if not tlog.is_file():
        raise UserError(f"{tlog}: no such file")
    out = out or tlog.with_suffix(".gif" if gif else ".png")
    drawn = render(tlog, out, gif, title)
    if as_json:
        print(json.dumps(drawn, indent=2))
    elif gif:
        print(
            f"wrote {out} ({drawn['width_px']}x{drawn['height_px']} px, {drawn['frames']} frames, "
            f"{drawn['bytes'] / 1024:.0f} KiB)"
        )
    else:
        # Decision frames, as `fly` counts its frames: a flight of N frames decides frames 0..N-1
        # and shows frame N's readings (the last move's outcome), N + 1 radio frames on the axis.
        span = drawn["frame_span"]
        frames = f" (radio frames {span[0]}-{span[1]})" if span else ""
        print(
            f"wrote {out} ({drawn['width_px']}x{drawn['height_px']} px): {drawn['tracks']} UAV "
            f"track(s), {drawn['ue_tracks']} UE track(s), {drawn['decision_frames']} decision "
            f"frames{frames}" + (f"; {'; '.join(drawn['notes'])}" if drawn["notes"] else "")
        )
    return 0
