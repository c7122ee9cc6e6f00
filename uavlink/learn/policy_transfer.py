"""A policy grown from another (ours): PPO starts from a trained policy whose observation lacks some
of the new one's inputs, e.g. a map policy (layout v3) from today's spatial policy (layout v1).

Every weight is copied; the first layer of the actor's and the critic's MLPs gets the old inputs'
columns where the same features sit in the new observation (matched by feature name, so a frame's
new fields may sit anywhere) and zeros for the new inputs (a privileged critic's own inputs,
``TrainConfig.critic``, after the observation: copied from a privileged critic, else new). The new policy's actions and values are
then the old one's exactly, whatever the new inputs read, and PPO can only learn to use them from
there: it starts at the old policy instead of at a copy of a rule (``uavlink.learn.imitation``),
so it cannot begin below it. Imports torch.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, cast

from uavlink.config import EnvConfig
from uavlink.env.observation import ObservationLayout
from uavlink.errors import UserError

FIRST_LAYERS = ("mlp_extractor.policy_net.0.weight", "mlp_extractor.value_net.0.weight")


def _column_map(source: ObservationLayout, target: ObservationLayout, path: Path) -> list[int]:
    """The new observation's column of each of the old one's features."""
    if (
        dataclasses.replace(source, version=target.version, place_cell_m=target.place_cell_m)
        != target
    ):
        raise UserError(
            f"warm_start.policy {path}: its observation ({source.describe()}) is not this env's "
            f"({target.describe()}) without the new fields"
        )
    column = {name: i for i, name in enumerate(target.feature_names())}
    missing = [name for name in source.feature_names() if name not in column]
    if missing:
        raise UserError(f"warm_start.policy {path}: this env's observation lacks {missing[0]}")
    return [column[name] for name in source.feature_names()]


def _first_layer_columns(
    columns: list[int], width: int, size: int, target_width: int
) -> list[int] | None:
    """Where a first layer's ``width`` inputs sit among the new one's ``target_width``: the old
    observation's at ``columns``, then a privileged critic's own inputs (uavlink/learn/privileged.py;
    after the observation of ``size`` in both) at the same places; None when they do not fit. A
    critic that reads the observation alone grows into a privileged one with those at zero."""
    tail = list(range(size, target_width))
    if width == len(columns):
        return columns
    return columns + tail if width == len(columns) + len(tail) else None


def start_from_policy(
    sb3_policy: Any, cfg: EnvConfig, path: str | Path, log_std: float | None = None
) -> dict[str, Any]:
    """Load the policy file ``path`` into ``sb3_policy`` (PPO's, for ``cfg``'s observation), the new
    inputs at zero weight; ``log_std`` resets the exploration (default: the file's). The report."""
    import torch
    from stable_baselines3.common.save_util import load_from_zip_file

    from uavlink.policies.contract import manifest_env
    from uavlink.policies.manifest import file_sha256, read_zip_manifest

    path = Path(path)
    source = ObservationLayout.for_config(manifest_env(read_zip_manifest(path)))
    layout = ObservationLayout.for_config(cfg)
    columns = _column_map(source, layout, path)
    _, params, _ = load_from_zip_file(path, device="cpu", print_system_info=False)
    target = sb3_policy.state_dict()
    loaded = {}
    # SB3 types ``params`` as name -> tensor; each entry is a module's state dict.
    policy_state = cast("dict[str, Any]", params["policy"])
    for name, value in policy_state.items():
        if name not in target:
            raise UserError(
                f"warm_start.policy {path}: its network has {name}, PPO's here does not"
            )
        mapped = (
            _first_layer_columns(columns, value.shape[1], layout.size, target[name].shape[1])
            if name in FIRST_LAYERS and value.shape[0] == target[name].shape[0]
            else None
        )
        if mapped is not None:
            grown = torch.zeros_like(target[name])
            grown[:, mapped] = value
            value = grown
        if value.shape != target[name].shape:
            raise UserError(
                f"warm_start.policy {path}: {name} is {tuple(value.shape)}, PPO's here "
                f"{tuple(target[name].shape)} (another net_arch or train.critic)"
            )
        loaded[name] = value
    absent = sorted(set(target) - set(loaded))
    if absent:
        raise UserError(f"warm_start.policy {path}: its network lacks {absent[0]}")
    sb3_policy.load_state_dict(loaded)
    if log_std is not None:
        with torch.no_grad():
            sb3_policy.log_std.fill_(log_std)
    return {
        "policy": str(path),
        "policy_sha256": file_sha256(path),
        "inputs_kept": len(columns),
        "inputs_new": layout.size - len(columns),
    }
