"""UE mobility scenarios, batched numpy with the random generator passed in; a fleet's start
positions, separation filter and setpoints (``fleet``), and the guard on what lagging vehicles sweep
between setpoints (``transit``), shared by the env and the flight loop; how a UAV flies to its
setpoint (``uav_motion``).

May import: ``config``, ``errors``.
"""

from uavlink.mobility.scenarios import (
    MIXED,
    SCENARIOS,
    MobilityState,
    draw_scenarios,
    init_mobility,
    scenario_index,
    step_mobility,
)

__all__ = [
    "MIXED",
    "SCENARIOS",
    "MobilityState",
    "draw_scenarios",
    "init_mobility",
    "scenario_index",
    "step_mobility",
]
