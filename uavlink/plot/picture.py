"""The picture of a flight (PNG) and its animation (GIF), drawn from :class:`FlightData` alone.

One function draws every flight picture (:func:`draw_flight`): ``uavlink fly`` hands it the data it
reads back from its own tlog, ``uavlink plot`` the data of any tlog, so both draw the same picture.
Above, the map: the fence, each UAV's track (one colour per vehicle, a dot per decision frame), the
UEs' tracks (the simulation's truth, coloured by their serving UAV), and the bearings (AoA) each
UAV sensed at the last frame. Below, the team's mean UE throughput and each UE's SINR at its
serving UAV over the frames, decision frames marked. :func:`animate_flight` draws the map once per
decision frame. matplotlib (the ``plot`` extra) is imported here only, with the Agg backend.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from uavlink.errors import missing_extra
from uavlink.plot.tlog import FlightData

UAV_COLOURS = (
    "#1f4e9c",
    "#c0392b",
    "#1e8449",
    "#7d3c98",
    "#d35400",
    "#17a589",
    "#5d6d7e",
    "#b7950b",
)


class PlotUnavailable(RuntimeError):
    """matplotlib is not installed (the torch-free ``[fly]`` install)."""


@dataclass(frozen=True)
class PictureInfo:
    """What a picture shows, for tests and callers."""

    path: Path
    width_px: int
    height_px: int
    tracks: int  # UAV tracks drawn
    ue_tracks: int  # UE tracks drawn (0 without the simulation's truth in the log)
    frames: int  # radio frames on the time axis
    decision_frames: int
    bearings: int  # sensed bearings drawn
    frame_span: tuple[int, int] | None = None  # first and last radio frame on the time axis


def source_name(data: FlightData) -> str:
    """The log's folder and name (``fly/flight.tlog``): the default title."""
    path = Path(data.source)
    return f"{path.parent.name}/{path.name}" if path.parent.name else path.name


def new_figure(width_in: float, height_in: float, dpi: float):
    """A matplotlib Figure on the Agg canvas (no pyplot: lighter to import, no GUI backend);
    PlotUnavailable without matplotlib."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ModuleNotFoundError as exc:
        raise PlotUnavailable(missing_extra(exc) or str(exc)) from None
    fig = Figure(figsize=(width_in, height_in), dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def uav_colour(d: int) -> str:
    return UAV_COLOURS[d % len(UAV_COLOURS)]


def ue_colours(n: int) -> list:
    import matplotlib

    cmap = matplotlib.colormaps["tab10" if n <= 10 else "tab20"]
    return [cmap(i % cmap.N) for i in range(n)]


def _map_extent_m(data: FlightData) -> float:
    """Half the side of the square the map shows: the fence, else everything drawn, plus a margin."""
    if data.fence_en_m is not None:
        half = float(np.abs(data.fence_en_m).max())
    else:
        parts = [np.abs(np.r_[v.east_m, v.north_m]) for v in data.vehicles]
        parts += [np.abs(a[np.isfinite(a)]) for a in (data.ue_east_m, data.ue_north_m)]
        half = max(max((float(p.max()) for p in parts if p.size), default=100.0), 20.0)
    return half * 1.06


def _frame_s(data: FlightData) -> float | None:
    times = [
        np.diff(v.frame_time_s) / np.maximum(np.diff(v.frames), 1)
        for v in data.vehicles
        if len(v.frames) > 1
    ]
    return float(np.median(np.concatenate(times))) if times else None


def draw_map(ax, data: FlightData, upto: int | None = None, bearings: bool = True) -> dict:
    """Fence, tracks, UEs and bearings on ``ax``; ``upto``: draw up to that row of
    ``data.frames`` only (the animation), else everything. Returns counts of what was drawn."""
    rows = len(data.frames) if upto is None else upto + 1
    half = _map_extent_m(data)
    ax.set_xlim(-half, half)
    ax.set_ylim(-half, half)
    ax.set_aspect("equal")
    from matplotlib.ticker import MaxNLocator

    for axis in (ax.xaxis, ax.yaxis):  # few ticks: each is text to lay out and draw
        axis.set_major_locator(MaxNLocator(6, steps=[1, 2, 5, 10]))
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.grid(True, lw=0.4, alpha=0.4)
    if data.fence_en_m is not None:
        poly = np.vstack([data.fence_en_m, data.fence_en_m[:1]])
        ax.plot(poly[:, 0], poly[:, 1], "k--", lw=1.2, label="fence")
    serving = data.serving_uav()
    if len(data.vehicles) < 2:  # one UAV serves every UE: its colour would only blur its own track
        serving = np.full_like(serving, -1)
    ue_colour = ue_colours(max(data.ue_east_m.shape[1], data.n_ues))
    ue_tracks, segments, colours, ends = 0, [], [], []
    for ue in range(data.ue_east_m.shape[1]):
        e, n = data.ue_east_m[:rows, ue], data.ue_north_m[:rows, ue]
        ok = np.isfinite(e)
        if not ok.any():
            continue
        ue_tracks += 1
        cell = serving[:rows, ue] if ue < serving.shape[1] else np.full(rows, -1)
        # one piece per stretch under one serving UAV (a handover changes the colour)
        starts = [
            i for i in range(rows) if ok[i] and (i == 0 or cell[i] != cell[i - 1] or not ok[i - 1])
        ]
        for s, end in zip(starts, [*starts[1:], rows], strict=True):
            segments.append(np.column_stack([e[s : end + 1], n[s : end + 1]]))
            colours.append(uav_colour(cell[s]) if cell[s] >= 0 else "0.55")
        last = np.flatnonzero(ok)[-1]
        ends.append((e[last], n[last], uav_colour(cell[last]) if cell[last] >= 0 else "0.55"))
        ax.annotate(
            str(ue),
            (e[last], n[last]),
            xytext=(4, 3),
            textcoords="offset points",
            fontsize=7,
            color=ue_colour[ue],
            fontweight="bold",
            zorder=5,
        )
    if segments:
        from matplotlib.collections import LineCollection

        ax.add_collection(LineCollection(segments, colors=colours, linewidths=1.0, alpha=0.45))
        east, north, face = zip(*ends, strict=True)
        ax.scatter(east, north, s=36, c=list(face), edgecolors="white", linewidths=0.8, zorder=4)
    n_bearings = 0
    for d, v in enumerate(data.vehicles):
        colour = uav_colour(d)
        keep = np.searchsorted(data.frames, v.frames) < rows
        if upto is None:
            ax.plot(
                v.east_m,
                v.north_m,
                "-",
                color=colour,
                lw=1.8,
                label=f"UAV {d + 1} (system {v.system_id}) track",
            )
        elif keep.any():
            t_end = v.frame_time_s[keep][-1]
            m = v.time_s <= t_end
            ax.plot(v.east_m[m], v.north_m[m], "-", color=colour, lw=1.8)
        fe, fn, dec = v.frame_east_m[keep], v.frame_north_m[keep], v.decided[keep]
        ax.plot(fe[dec], fn[dec], ".", color=colour, ms=3.5, zorder=3)
        if len(fe):
            ax.plot(fe[-1], fn[-1], "^", ms=10, mfc=colour, mec="black", mew=0.8, zorder=6)
        if bearings and len(fe) and v.aoa_deg.shape[1]:
            ray = 0.3 * half
            for ue, deg in enumerate(v.aoa_deg[keep][-1]):
                if not np.isfinite(deg) or (v.serves is not None and not v.serves[keep][-1][ue]):
                    continue
                a = np.radians(deg)
                ax.plot(
                    [fe[-1], fe[-1] + ray * np.cos(a)],
                    [fn[-1], fn[-1] + ray * np.sin(a)],
                    "-",
                    color=ue_colour[ue],
                    lw=0.9,
                    alpha=0.85,
                    zorder=2,
                )
                n_bearings += 1
    return {"ue_tracks": ue_tracks, "bearings": n_bearings}


def _legend_handles(data: FlightData):
    from matplotlib.lines import Line2D

    handles = (
        [Line2D([], [], color="k", ls="--", label="fence")] if data.fence_en_m is not None else []
    )
    for d, v in enumerate(data.vehicles):
        handles.append(
            Line2D(
                [],
                [],
                color=uav_colour(d),
                lw=1.8,
                marker="^",
                ms=7,
                mec="black",
                label=f"UAV {d + 1} (system {v.system_id}): track, decisions, end",
            )
        )
    if data.ue_east_m.shape[1]:
        by_uav = " (colour: serving UAV)" if len(data.vehicles) > 1 else ""
        handles.append(
            Line2D(
                [],
                [],
                color="0.45",
                lw=1,
                marker="o",
                ms=6,
                mec="white",
                alpha=0.8,
                label=f"UE track, now{by_uav}",
            )
        )
    if data.n_ues:
        handles.append(
            Line2D([], [], color="0.3", lw=0.9, label="sensed bearing (AoA), last frame")
        )
    return handles


def draw_flight(data: FlightData, out: Path, title: str | None = None) -> PictureInfo:
    """The flight picture as a PNG at ``out``; PlotUnavailable without matplotlib."""
    fig = new_figure(7.6, 10.4, 100)
    grid = fig.add_gridspec(
        3,
        1,
        height_ratios=[3.5, 1.0, 1.25],
        hspace=0.2,
        left=0.12,
        right=0.97,
        top=0.935,
        bottom=0.055,
    )
    ax_map = fig.add_subplot(grid[0])
    drawn = draw_map(ax_map, data)
    ax_map.legend(handles=_legend_handles(data), loc="upper left", fontsize=7.5, framealpha=0.85)
    ax_rate = fig.add_subplot(grid[1])
    ax_sinr = fig.add_subplot(grid[2], sharex=ax_rate)
    _draw_rate(ax_rate, data)
    _draw_sinr(ax_sinr, data)
    ax_rate.tick_params(labelbottom=False)  # the SINR panel below labels the shared frame axis
    frame_s = _frame_s(data)
    ax_sinr.set_xlabel("radio frame" + (f" ({frame_s:.3g} s each)" if frame_s else ""))
    mean = np.nanmean(data.mean_rate_mbps) if np.isfinite(data.mean_rate_mbps).any() else None
    head = title or source_name(data)
    summary = (
        f"{len(data.vehicles)} UAV{'s' if len(data.vehicles) > 1 else ''}, "
        f"{data.n_ues} UEs, {data.decision_frames} decision frames"
        + (f", mean UE throughput {mean:.2f} Mbps" if mean is not None else "")
    )
    fig.suptitle(f"{head}\n{summary}", fontsize=11)
    if data.notes:
        fig.text(0.5, 0.005, "; ".join(data.notes), ha="center", fontsize=7.5, color="0.35")
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.canvas.draw()
    width, height = fig.canvas.get_width_height()
    _save_png(np.asarray(fig.canvas.buffer_rgba())[..., :3], out)
    span = (int(data.frames[0]), int(data.frames[-1])) if len(data.frames) else None
    return PictureInfo(
        out,
        width,
        height,
        len(data.vehicles),
        drawn["ue_tracks"],
        len(data.frames),
        data.decision_frames,
        drawn["bearings"],
        span,
    )


def _save_png(rgb: np.ndarray, out: Path) -> None:
    """A 256-colour PNG: a quarter of the RGBA file matplotlib writes, the same to the eye for a
    picture of lines and text."""
    from PIL import Image  # matplotlib's own dependency

    Image.fromarray(rgb).quantize(256, method=Image.Quantize.FASTOCTREE).save(out, format="PNG")


def _mark_decisions(ax, data: FlightData) -> None:
    """A tick along the bottom of ``ax`` at every decision frame, one row per UAV."""
    for d, v in enumerate(data.vehicles):
        f = v.frames[v.decided]
        if len(f):
            ax.plot(
                f,
                np.zeros(len(f)) + 0.02 + 0.05 * d,
                "|",
                color=uav_colour(d),
                ms=5,
                mew=0.8,
                transform=ax.get_xaxis_transform(),
                clip_on=False,
                label="decision frames" if d == 0 else None,
            )


def _draw_rate(ax, data: FlightData) -> None:
    ax.set_ylabel("mean UE\nthroughput (Mbps)")
    ax.grid(True, lw=0.4, alpha=0.4)
    rate = data.mean_rate_mbps
    if np.isfinite(rate).any():
        ax.plot(data.frames, rate, "-", color="0.15", lw=1.2, label="mean UE throughput")
        mean = float(np.nanmean(rate))
        ax.axhline(mean, color="0.5", ls=":", lw=1, label=f"flight mean {mean:.2f} Mbps")
        ax.set_ylim(bottom=0)
    else:
        ax.text(
            0.5,
            0.5,
            "no throughput (UL_SCORE) in the log",
            ha="center",
            va="center",
            transform=ax.transAxes,
            color="0.4",
        )
    _mark_decisions(ax, data)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="lower right", fontsize=7.5, framealpha=0.85)


def _draw_sinr(ax, data: FlightData) -> None:
    """Each UE's SINR at its serving UAV (the only UAV's, for one)."""
    ax.set_ylabel("UE SINR at its\nserving UAV (dB)")
    ax.grid(True, lw=0.4, alpha=0.4)
    if not data.n_ues:
        ax.text(
            0.5,
            0.5,
            "no radio readings (UL_RADIO) in the log",
            ha="center",
            va="center",
            transform=ax.transAxes,
            color="0.4",
        )
        return
    sinr = np.full((len(data.frames), data.n_ues), np.nan)
    serving = data.serving_uav()
    for d, v in enumerate(data.vehicles):
        rows = np.searchsorted(data.frames, v.frames)
        mine = serving[rows] == d
        sinr[rows] = np.where(mine, v.sinr_db, sinr[rows])
    from matplotlib.collections import LineCollection

    lines = [np.column_stack([data.frames, sinr[:, ue]]) for ue in range(data.n_ues)]
    ax.add_collection(
        LineCollection(lines, colors=ue_colours(data.n_ues), linewidths=0.9, alpha=0.85)
    )
    ax.autoscale_view()
    ax.text(
        1.0,
        1.02,
        "one line per UE (colour: UE number on the map)",
        transform=ax.transAxes,
        ha="right",
        fontsize=7.5,
        color="0.35",
    )
