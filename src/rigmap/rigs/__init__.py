"""Rigs: the black-box function from controls to joint positions (paper §3)."""

from rigmap.rigs.base import (
    Control,
    ControlTable,
    Pose,
    Rig,
    RigInputError,
    UnknownRigError,
    check_placement,
    check_positions,
)
from rigmap.rigs.registry import available, load, register, use_executor

__all__ = [
    "Control",
    "ControlTable",
    "Pose",
    "Rig",
    "RigInputError",
    "UnknownRigError",
    "available",
    "check_placement",
    "check_positions",
    "load",
    "register",
    "use_executor",
]
