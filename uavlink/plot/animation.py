"""The flight as an animated GIF: the map of :func:`uavlink.plot.picture.draw_map`, one GIF frame
per decision frame (every radio frame when the log has no decision), and the team's mean UE
throughput with the frame marked underneath.

Kept small (a few hundred kilobytes for a 128-frame flight): a small canvas, one shared 48-colour
palette without dithering, each frame drawn over a still background (blitting) and storing only
the pixels that changed (the others transparent).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from uavlink.plot.picture import draw_map, new_figure, source_name, uav_colour, ue_colours
from uavlink.plot.tlog import FlightData

FRAME_MS = 120  # GIF frame duration: 128 decisions in about 15 s
PALETTE_COLOURS = 48
TRANSPARENT = PALETTE_COLOURS  # the palette index of "as before"
TAIL_FRAMES = 12  # frames of each UE's track shown behind it


@dataclass(frozen=True)
class AnimationInfo:
    path: Path
    frames: int  # GIF frames (one per decision frame)
    width_px: int
    height_px: int
    bytes: int


def animate_flight(data: FlightData, out: Path, title: str | None = None) -> AnimationInfo:
    """Write the animation to ``out`` (a GIF); PlotUnavailable without matplotlib."""
    from PIL import Image  # matplotlib's own dependency

    rows = _animated_rows(data)
    fig = new_figure(4.8, 5.9, 80)
    grid = fig.add_gridspec(
        2, 1, height_ratios=[4.2, 1.0], hspace=0.35, left=0.16, right=0.96, top=0.93, bottom=0.09
    )
    ax_map, ax_rate = fig.add_subplot(grid[0]), fig.add_subplot(grid[1])
    scene = _MapScene(ax_map, data)
    rate = data.mean_rate_mbps
    has_rate = bool(np.isfinite(rate).any())
    ax_rate.set_xlabel("radio frame")
    ax_rate.set_ylabel("mean UE\nrate (Mbps)")
    ax_rate.grid(True, lw=0.4, alpha=0.4)
    if has_rate:
        ax_rate.plot(data.frames, rate, "-", color="0.78", lw=1.0)
        ax_rate.set_ylim(0, np.nanmax(rate) * 1.1)
    if len(data.frames):
        ax_rate.set_xlim(data.frames[0], max(data.frames[-1], data.frames[0] + 1))
    (done,) = ax_rate.plot([], [], "-", color="0.1", lw=1.2)
    cursor = ax_rate.axvline(0, color="#c0392b", lw=1.0)
    heading = fig.suptitle(" ", fontsize=9.5)
    head = title or source_name(data)
    moving = [*scene.artists, done, cursor, heading]
    for artist in moving:
        artist.set_animated(True)  # drawn per frame over the still background (blitting)
    canvas = fig.canvas
    canvas.draw()
    background = canvas.copy_from_bbox(fig.bbox)
    images, palette, previous = [], None, None
    for row in rows:
        if row >= 0:
            scene.show(row)
            frame = int(data.frames[row])
            done.set_data(data.frames[: row + 1], rate[: row + 1])
            cursor.set_xdata([frame, frame])
            now = f", {rate[row]:.2f} Mbps" if has_rate and np.isfinite(rate[row]) else ""
            heading.set_text(f"{head}: frame {frame}{now}")
        canvas.restore_region(background)
        for artist in moving:
            fig.draw_artist(artist)
        rgb = Image.fromarray(np.asarray(canvas.buffer_rgba())[..., :3])
        if palette is None:
            palette = rgb.quantize(PALETTE_COLOURS, dither=Image.Dither.NONE)
        index = np.asarray(rgb.quantize(palette=palette, dither=Image.Dither.NONE))
        # pixels as in the previous frame become the transparent index: LZW packs those runs
        # into almost nothing, so a frame costs what moved
        shown = index if previous is None else np.where(index == previous, TRANSPARENT, index)
        previous = index
        image = Image.fromarray(shown.astype(np.uint8), "P")
        colours = palette.getpalette()
        assert colours is not None  # a quantized image has a palette
        image.putpalette(colours)
        images.append(image)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    images[0].save(
        out,
        save_all=True,
        append_images=images[1:],
        duration=FRAME_MS,
        loop=0,
        optimize=False,
        disposal=1,
        transparency=TRANSPARENT,
    )
    width, height = images[0].size
    return AnimationInfo(out, len(images), width, height, out.stat().st_size)


def _animated_rows(data: FlightData) -> np.ndarray:
    """Rows of ``data.frames`` to animate: the decision frames, else every frame."""
    decided = np.zeros(len(data.frames), dtype=bool)
    for v in data.vehicles:
        decided[np.searchsorted(data.frames, v.frames[v.decided])] = True
    rows = np.flatnonzero(decided) if decided.any() else np.arange(len(data.frames))
    return rows if len(rows) else np.array([-1])


class _MapScene:
    """The map's moving parts, made once and moved each frame (redrawing the axes per frame would
    cost ten times as much)."""

    def __init__(self, ax, data: FlightData) -> None:
        from matplotlib.collections import LineCollection

        self.data, self.ax = data, ax
        draw_map(ax, data, upto=-1, bearings=False)  # fence, axes, labels: the still parts
        self.serving = data.serving_uav()
        self.ue_colours = [
            tuple(c) for c in ue_colours(max(data.n_ues, data.ue_east_m.shape[1], 1))
        ]
        self.trails = [
            ax.plot([], [], "-", color=uav_colour(d), lw=1.6)[0] for d in range(len(data.vehicles))
        ]
        self.uavs = [
            ax.plot([], [], "^", ms=9, mfc=uav_colour(d), mec="black", mew=0.8, zorder=6)[0]
            for d in range(len(data.vehicles))
        ]
        self.tails = LineCollection([], lw=1.0, alpha=0.5)
        self.rays = LineCollection([], lw=0.9, alpha=0.85, zorder=2)
        ax.add_collection(self.tails)
        ax.add_collection(self.rays)
        self.ues = ax.scatter([], [], s=30, edgecolors="white", linewidths=0.7, zorder=4)
        self.ray_m = 0.3 * ax.get_xlim()[1]
        self.artists = [*self.trails, *self.uavs, self.tails, self.rays, self.ues]

    def show(self, row: int) -> None:
        data = self.data
        rays, ray_colours = [], []
        for d, v in enumerate(data.vehicles):
            keep = np.searchsorted(data.frames, v.frames) <= row
            if not keep.any():
                continue
            k = np.flatnonzero(keep)[-1]
            upto = v.time_s <= v.frame_time_s[k]
            self.trails[d].set_data(v.east_m[upto], v.north_m[upto])
            e, n = v.frame_east_m[k], v.frame_north_m[k]
            self.uavs[d].set_data([e], [n])
            for ue, deg in enumerate(v.aoa_deg[k]):
                if np.isfinite(deg) and (v.serves is None or v.serves[k][ue]):
                    a = np.radians(deg)
                    rays.append([(e, n), (e + self.ray_m * np.cos(a), n + self.ray_m * np.sin(a))])
                    ray_colours.append(self.ue_colours[ue])
        self.rays.set_segments(rays)
        self.rays.set_colors(ray_colours)
        lo = max(0, row - TAIL_FRAMES)
        east, north = data.ue_east_m[lo : row + 1], data.ue_north_m[lo : row + 1]
        now = np.isfinite(east[-1]) if len(east) else np.zeros(0, bool)
        cells = (
            self.serving[row, : east.shape[1]]
            if east.shape[1] <= self.serving.shape[1]
            else np.full(east.shape[1], -1)
        )
        colours = [uav_colour(c) if c >= 0 else "0.55" for c in cells]
        self.tails.set_segments(
            [np.column_stack([east[:, u], north[:, u]]) for u in range(east.shape[1])]
        )
        self.tails.set_colors(colours)
        self.ues.set_offsets(
            np.column_stack([east[-1][now], north[-1][now]]) if now.any() else np.zeros((0, 2))
        )
        self.ues.set_facecolors([c for c, ok in zip(colours, now, strict=True) if ok])
