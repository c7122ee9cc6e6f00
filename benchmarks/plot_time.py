"""What the flight picture adds to `uavlink fly`: the time to read a real flight's tlog and draw
flight.png (matplotlib's Agg canvas), in a fresh process that has imported what fly has when the
picture is drawn (uavlink, pymavlink; not matplotlib, whose import is counted).

Flies one episode through the embedded SITL (`uavlink fly --policy aoa --no-picture`, 128 frames by
default) unless --tlog is given, then draws its picture --repeats times, each in a new process, and
reports the median and the parts (reading the log, importing matplotlib, drawing and writing the
PNG) in wall time and in the process's CPU time, with the machine's load average. On a shared
machine the wall time counts the others' work too (load 10 on 2 cores: about 5x); the CPU time is
what the drawing itself costs, the wall time it takes on an idle core (it runs on one thread).
Target: under 2 s for a 128-frame flight on 2 cores. With --gif, the animation's time,
frames and size too.

    python benchmarks/plot_time.py [--tlog FLIGHT.tlog] [--frames 128] [--speed 20] [--repeats 3]
                                   [--gif] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = """
import json, sys, time
from pathlib import Path
import uavlink.flight.fly, uavlink.flight.link  # what fly has imported when it draws
from uavlink.plot.tlog import read_flight
tlog, out, gif = Path(sys.argv[1]), Path(sys.argv[2]), sys.argv[3] == "1"
c0, t0 = time.process_time(), time.perf_counter()
data = read_flight(tlog)
c1, t1 = time.process_time(), time.perf_counter()
import matplotlib.figure, matplotlib.backends.backend_agg
c2, t2 = time.process_time(), time.perf_counter()
if gif:
    from uavlink.plot.animation import animate_flight
    info = animate_flight(data, out)
    extra = {"gif_frames": info.frames, "gif_bytes": info.bytes}
else:
    from uavlink.plot.picture import draw_flight
    info = draw_flight(data, out)
    extra = {"frames": info.frames, "decision_frames": info.decision_frames}
c3, t3 = time.process_time(), time.perf_counter()
print(json.dumps({"total_s": t3 - t0, "read_s": t1 - t0, "import_s": t2 - t1, "draw_s": t3 - t2,
                  "total_cpu_s": c3 - c0, "read_cpu_s": c1 - c0, "import_cpu_s": c2 - c1,
                  "draw_cpu_s": c3 - c2, **extra}))
"""


def _child(tlog: Path, out: Path, gif: bool) -> dict:
    env = dict(
        os.environ,
        PYTHONPATH=os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p),
    )
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, str(tlog), str(out), "1" if gif else "0"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=600,
        env=env,
    )
    if proc.returncode != 0:
        raise SystemExit(f"drawing failed: {proc.stderr.strip()[-2000:]}")
    return json.loads(proc.stdout)


def _fly(frames: int, speed: float, out: Path) -> dict:
    cmd = [
        sys.executable,
        "-m",
        "uavlink.cli",
        "fly",
        "--policy",
        "aoa",
        "--frames",
        str(frames),
        "--speed",
        f"{speed:g}",
        "--out",
        str(out),
        "--no-picture",
        "--json",
        "--quiet",
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=600)
    if proc.returncode != 0:
        raise SystemExit(f"fly failed: {proc.stderr.strip()[-2000:]}")
    return json.loads(proc.stdout)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--tlog", type=Path, default=None, help="a flight's tlog (default: fly one)"
    )
    parser.add_argument("--frames", type=int, default=128, help="frames to fly without --tlog")
    parser.add_argument(
        "--speed",
        type=float,
        default=20.0,
        help="the flight's speed factor (lower it on a loaded machine)",
    )
    parser.add_argument(
        "--repeats", type=int, default=3, help="pictures drawn, each in a new process"
    )
    parser.add_argument("--gif", action="store_true", help="time the animation too (once)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        flight = None
        tlog = args.tlog
        if tlog is None:
            flight = _fly(args.frames, args.speed, Path(tmp) / "fly")
            tlog = Path(flight["tlog"])
        tlog_bytes = tlog.stat().st_size
        load_before = os.getloadavg()[0]
        runs = [_child(tlog, Path(tmp) / f"p{i}.png", False) for i in range(args.repeats)]
        gif = _child(tlog, Path(tmp) / "flight.gif", True) if args.gif else None
        load_after = os.getloadavg()[0]
    median = {
        k: round(statistics.median(r[k] for r in runs), 3)
        for k in (
            "total_s",
            "read_s",
            "import_s",
            "draw_s",
            "total_cpu_s",
            "read_cpu_s",
            "import_cpu_s",
            "draw_cpu_s",
        )
    }
    result = {
        "tlog": str(args.tlog) if args.tlog else f"uavlink fly --policy aoa --frames {args.frames}",
        "tlog_bytes": tlog_bytes,
        "frames": runs[0]["frames"],
        "decision_frames": runs[0]["decision_frames"],
        "repeats": args.repeats,
        "picture_s_median": median["total_s"],
        "picture_cpu_s_median": median["total_cpu_s"],
        "parts_s_median": median,
        "picture_s_all": [round(r["total_s"], 3) for r in runs],
        "flight_wall_s": None if flight is None else flight["wall_s"],
        "cpu_count": os.cpu_count(),
        "load_avg_1min": [round(load_before, 2), round(load_after, 2)],
        "target_s": 2.0,
    }
    if gif is not None:
        result["gif"] = {
            "seconds": round(gif["total_s"], 2),
            "frames": gif["gif_frames"],
            "bytes": gif["gif_bytes"],
        }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(
            f"picture of {result['frames']} frames: median {median['total_s']:.2f} s wall, "
            f"{median['total_cpu_s']:.2f} s CPU (read "
            f"{median['read_s']:.2f}, import matplotlib {median['import_s']:.2f}, draw "
            f"{median['draw_s']:.2f}); target < 2 s; load average {result['load_avg_1min']} on "
            f"{result['cpu_count']} CPUs"
            + (f"; flight {result['flight_wall_s']} s" if flight else "")
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
