"""Sweeps: scenarios x seeds x settings, each job train + evaluate, run on Dask distributed.

``sweep_file`` reads and checks a sweep file into a ``spec``, which expands into jobs with stable
keys (no dask needed); ``jobs`` is the job function a worker runs; ``runner`` is the client side (embedded LocalCluster or
``--scheduler``); ``aggregate`` writes the per-setting tables and plots, and ``report_sections``
sorts a results report's sweeps into its parts. Only ``runner`` imports
dask, so the core and flight installs never need it.

May import: ``config``, ``errors``, ``seeding``, ``env``, ``rollout``, ``policies``, ``learn``, ``evaluation``.
"""

from uavlink.sweep.spec import Job, SweepSpec, SweepSpecError
from uavlink.sweep.sweep_file import load_spec

__all__ = ["Job", "SweepSpec", "SweepSpecError", "load_spec"]
