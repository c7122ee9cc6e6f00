"""Policies: the shared interface, rule-based baselines (one UAV's in ``baselines``, a fleet's in
``fleet_baselines``, both by name in ``registry``), and loaders for policy files, manifests and the
policy contract.

May import: ``config``, ``errors``, ``seeding``, ``radio``, ``mobility``, ``env``, ``rollout``.
"""

from uavlink.policies.base import Policy
from uavlink.policies.baselines import AoaPolicy, OraclePolicy, StaticPolicy
from uavlink.policies.registry import BASELINES, make_baseline

__all__ = ["BASELINES", "AoaPolicy", "OraclePolicy", "Policy", "StaticPolicy", "make_baseline"]
