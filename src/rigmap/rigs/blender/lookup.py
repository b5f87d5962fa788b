"""A Blender rig from a rig, a rig name or a rig config, and the entry points taking any of them.

The modules below it (:mod:`.rig`, :mod:`.retarget`) work on a built
:class:`~rigmap.rigs.blender.rig.BlenderRig`; resolving a name goes through
:func:`rigmap.rigs.load` here, so no module under the rig imports the registry.
"""

from __future__ import annotations

from rigmap.errors import RigmapError
from rigmap.rigs.base import Rig
from rigmap.rigs.blender.rig import BlenderRig
from rigmap.rigs.registry import load


class NotBlenderRigError(RigmapError, TypeError, ValueError):
    """A rig that is not a Blender rig where one is needed (a user's choice of rig: a
    ``ValueError`` too, so entry points report it as bad input)."""


def blender_rig(rig_config_or_rig) -> BlenderRig:
    """The :class:`BlenderRig` named by a rig, a rig name or a rig config."""
    rig = rig_config_or_rig if isinstance(rig_config_or_rig, Rig) else load(rig_config_or_rig)
    if not isinstance(rig, BlenderRig):
        raise NotBlenderRigError(
            f"rig {rig.name!r} is a {type(rig).__name__}, not a Blender rig; "
            "only Blender rigs (rigify_human, rigify_wolf, blend_file) can be written to .blend"
        )
    return rig


def constraint_retarget(rig_config_or_rig, positions, cog=None, cog_rotation=None, *, mapping=None):
    """Control vectors ``(N, C)`` from the constraint-based retarget of a Blender rig.

    See :func:`rigmap.rigs.blender.retarget.solve_constraints`; the rig may be given
    by name or config, and the mapping defaults to the rig's ``retarget`` list.
    """
    rig = blender_rig(rig_config_or_rig)
    return rig.constraint_retarget(positions, cog, cog_rotation, mapping=mapping)
