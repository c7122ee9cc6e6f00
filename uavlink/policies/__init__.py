"""Policies: the shared interface, rule-based baselines, and loaders for policy files."""

from uavlink.policies.base import Policy
from uavlink.policies.baselines import (
    BASELINES,
    AoaPolicy,
    OraclePolicy,
    StaticPolicy,
    make_baseline,
)

__all__ = ["BASELINES", "AoaPolicy", "OraclePolicy", "Policy", "StaticPolicy", "make_baseline"]
