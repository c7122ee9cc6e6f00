"""The sweeps a results report shows (``uavlink evaluate --out --sweep ...``): each sweep's kind
(one UAV on the AR(1) or the spatial channel, a fleet, a memory of place), the folder its median
seeds were shipped to (its record lies beside them), and its markdown section under its kind's
part of docs/results.md."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from uavlink.sweep.aggregate import finished_rows, read_record, record_path, results_section
from uavlink.sweep.spec import SweepSpec

FLEET, MAP = "fleet", "map"  # besides the shadowing models, "ar1" and "spatial"


@dataclass(frozen=True)
class ReportSweeps:
    """``specs`` read from ``sweep_root``; the shipped folders by kind (``policies``: one UAV on the
    AR(1) channel, and any kind without a folder of its own); figures drawn into ``assets``."""

    specs: Sequence[SweepSpec]
    sweep_root: Path
    assets: Path
    policies: Path
    spatial: Path | None = None
    fleet: Path | None = None
    fleet_per_size: Path | None = None
    map: Path | None = None

    @staticmethod
    def kind(spec: SweepSpec) -> str:
        env = spec.jobs()[0].env
        if env.n_uavs > 1:
            return FLEET
        return MAP if env.place_cell_m > 0 else env.radio.shadowing_model

    def shipped(self, spec: SweepSpec) -> Path:
        """Where the sweep's median seeds were shipped (a sweep of per-size fleet policies,
        fleet_slots 0, beside ``fleet_per_size``'s when given)."""
        fleet = self.fleet
        if self.fleet_per_size is not None and spec.jobs()[0].env.fleet_slots == 0:
            fleet = self.fleet_per_size
        by_kind = {FLEET: fleet, MAP: self.map, "spatial": self.spatial}
        return by_kind.get(self.kind(spec)) or self.policies

    def check_finished(self) -> None:
        """A UserError naming any sweep with jobs neither in ``sweep_root`` nor in its record:
        before the long evaluation, which would write the report."""
        for spec in self.specs:
            finished_rows(
                spec,
                self.sweep_root / spec.name,
                read_record(record_path(self.shipped(spec), spec)),
            )

    def sections(self, link_prefix: Path, kind: str) -> list[str]:
        """The markdown sections of the sweeps of ``kind``, each followed by a blank line; one UAV
        on the AR(1) channel at the top level (``##``), the others inside their part (``###``)."""
        return [
            section
            for spec in self.specs
            if self.kind(spec) == kind
            for section in (
                results_section(
                    spec,
                    self.sweep_root / spec.name,
                    self.assets,
                    link_prefix,
                    self.shipped(spec),
                    "##" if kind == "ar1" else "###",
                ),
                "",
            )
        ]
