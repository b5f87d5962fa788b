"""The built-in face driven by ARKit's 52 blendshapes: real capture curves on a mesh (ours).

Live Link Face records a performance as ARKit's 52 blendshape weights over time
(:mod:`rigmap.latent.live_link`). This rig takes exactly those as its controls, named as
ARKit names them (``eyeBlinkLeft`` … ``tongueOut``, each a weight in [0, 1]), so captured
curves drive a mesh whose surface errors are centimetres, and latent synthesis scales and
reduces them as it does the built-in face's sliders.

The mesh and its deformation are the built-in face's (:mod:`rigmap.rigs.characters.face`:
3 362 vertices, clamped sliders, combination correctives, a skinned jaw). Each ARKit shape
is a fixed linear combination of that face's sliders and jaw channels, chosen by ARKit's
meaning of its name (``ARKIT_TO_FACE``; the weights are ours, not a measurement). ARKit's
"Left" is the performer's left, which is the character's left (+X) here. Three limits,
each because the head has no geometry for it:

- ``eyeLookIn*`` and ``eyeLookOut*`` turn the eyeball, and the head has no eyeball apart
  from its skin: they move nothing (unused controls); ``eyeLookUp*`` / ``eyeLookDown*``
  move the lids as an eye looking up or down does;
- ``tongueOut``: the head has no tongue; it moves nothing (an unused control);
- the eye and head rotation columns of a Live Link Face CSV are not controls.

Joints are the built-in face's six landmarks; :meth:`mesh` gives every vertex.
"""

from __future__ import annotations

import numpy as np
import torch

from rigmap.rigs.base import Control
from rigmap.rigs.characters.face import (
    FaceModel,
    FaceRig,
    build_face_model,
)
from rigmap.rigs.mesh.rig import DeformedMesh

#: the face's jaw at an ARKit weight of 1 (ours: the face's own control ranges' ends)
JAW_OPEN_RAD = 0.45  # jawOpen: jaw.rx at the top of its range
JAW_SIDE_RAD = 0.15  # jawLeft / jawRight: jaw.ry (+ turns the chin to the character's left)
JAW_FORWARD_CM = 0.6  # jawForward: jaw.tz
#: a lid follows the eye's gaze (ours): how far toward a blink (down) or wide (up)
LID_FOLLOWS_DOWN = 0.3
LID_FOLLOWS_UP = 0.4


def _sided(arkit: str, face: str, weight: float = 1.0) -> dict[str, dict[str, float]]:
    return {f"{arkit}Left": {f"{face}_l": weight}, f"{arkit}Right": {f"{face}_r": weight}}


def _eye(side: str, s: str) -> dict[str, dict[str, float]]:
    """One eye's seven shapes in ARKit's order (``side`` Left/Right, the face's ``s`` l/r)."""
    return {
        f"eyeBlink{side}": {f"eye_blink_{s}": 1.0},
        f"eyeLookDown{side}": {f"eye_blink_{s}": LID_FOLLOWS_DOWN},
        f"eyeLookIn{side}": {},
        f"eyeLookOut{side}": {},
        f"eyeLookUp{side}": {f"eye_wide_{s}": LID_FOLLOWS_UP},
        f"eyeSquint{side}": {f"eye_squint_{s}": 1.0},
        f"eyeWide{side}": {f"eye_wide_{s}": 1.0},
    }


#: each ARKit blendshape as face controls and the amount of each at a weight of 1, in
#: ARKit's (and Live Link Face's) order
ARKIT_TO_FACE: dict[str, dict[str, float]] = {
    **_eye("Left", "l"),
    **_eye("Right", "r"),
    "jawForward": {"jaw.tz": JAW_FORWARD_CM},
    "jawRight": {"jaw.ry": -JAW_SIDE_RAD},
    "jawLeft": {"jaw.ry": JAW_SIDE_RAD},
    "jawOpen": {"jaw.rx": JAW_OPEN_RAD},
    "mouthClose": {"mouth_close": 1.0},
    "mouthFunnel": {"mouth_funnel": 1.0},
    "mouthPucker": {"mouth_pucker": 1.0},
    "mouthRight": {"mouth_shift": -1.0},
    "mouthLeft": {"mouth_shift": 1.0},
    **_sided("mouthSmile", "mouth_smile"),
    **_sided("mouthFrown", "mouth_frown"),
    **_sided("mouthDimple", "mouth_dimple"),
    **_sided("mouthStretch", "mouth_stretch"),
    "mouthRollLower": {"mouth_roll_lower": 1.0},
    "mouthRollUpper": {"mouth_roll_upper": 1.0},
    "mouthShrugLower": {"mouth_shrug_lower": 1.0},
    "mouthShrugUpper": {"mouth_shrug_upper": 1.0},
    **_sided("mouthPress", "mouth_press"),
    **_sided("mouthLowerDown", "lower_lip_depress"),
    **_sided("mouthUpperUp", "upper_lip_raise"),
    **_sided("browDown", "brow_down"),
    "browInnerUp": {"brow_inner_up_l": 1.0, "brow_inner_up_r": 1.0},
    **_sided("browOuterUp", "brow_outer_up"),
    "cheekPuff": {"cheek_puff_l": 1.0, "cheek_puff_r": 1.0},
    **_sided("cheekSquint", "cheek_raise"),
    **_sided("noseSneer", "nose_wrinkle"),
    "tongueOut": {},
}
ARKIT_ORDER = tuple(ARKIT_TO_FACE)  # the dict is written in ARKit's order
GROUPS = (("eye", "eyes"), ("jaw", "jaw"), ("mouth", "mouth"), ("brow", "brows"))


def arkit_controls() -> list[Control]:
    """52 weights in [0, 1] (rest 0), ARKit's order; a shape that moves nothing is unused."""
    return [
        Control(name, "scalar", 0.0, 0.0, 1.0, bool(ARKIT_TO_FACE[name]), _group(name))
        for name in ARKIT_ORDER
    ]


def _group(name: str) -> str:
    return next((group for prefix, group in GROUPS if name.startswith(prefix)), "cheeks_nose")


def arkit_matrix(face_names: list[str]) -> np.ndarray:
    """``(52, len(face_names))``: face controls = ARKit weights @ this matrix."""
    matrix = np.zeros((len(ARKIT_ORDER), len(face_names)))
    for row, name in enumerate(ARKIT_ORDER):
        for face_control, amount in ARKIT_TO_FACE[name].items():
            matrix[row, face_names.index(face_control)] = amount
    return matrix


def build_arkit_face(*, chunk: int = 4096) -> ArkitFaceRig:
    """The ARKit face rig (52 controls -> 6 landmarks)."""
    return ArkitFaceRig(build_face_model(), chunk=chunk)


class ArkitFaceRig(FaceRig):
    """The built-in face's mesh and deformation, its controls ARKit's 52 weights."""

    def __init__(self, model: FaceModel, *, chunk: int = 4096):
        super().__init__(
            model,
            chunk=chunk,
            name="arkit_face",
            controls=arkit_controls(),
            description=(
                "The procedural face driven by ARKit's 52 blendshape weights (a fixed map "
                "to its sliders and jaw, ours); 6 landmarks (cm)"
            ),
        )
        self.arkit_matrix = arkit_matrix(self.face_control_names)

    def face_values(self, Y) -> np.ndarray | torch.Tensor:
        """The built-in face's controls ``(N, 49)`` for ARKit weights ``(N, 52)``."""
        if isinstance(Y, torch.Tensor):
            return Y @ torch.as_tensor(self.arkit_matrix, dtype=Y.dtype)
        return np.asarray(Y, dtype=np.float64) @ self.arkit_matrix

    def _deform(self, Y: torch.Tensor, vertex_index) -> DeformedMesh:
        return self._deform_face(self.face_values(Y), vertex_index)
