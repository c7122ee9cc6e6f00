"""``genie``, the full-knowledge yardstick (evaluation only): ``grid`` (the one-UAV dynamic programme
over a grid of positions), ``separation`` (a fleet's move checks) and ``policy`` (the policy: plans on
the episode's future, a fleet UAV by UAV). Part of ``uavlink.policies``.

May import: what ``uavlink.policies`` may (layers 0-4) and that package's rules (``fleet_baselines``);
never ``registry``, which builds the genie with its reference baselines."""

from uavlink.policies.genie.policy import REFERENCES, GeniePolicy, fleet_mean_rate_bps

__all__ = ["REFERENCES", "GeniePolicy", "fleet_mean_rate_bps"]
