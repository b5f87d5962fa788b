"""The Pose page's side in Python: a :class:`PoseDriver` behind its websocket.

Commands: ``rig`` (load a rig by name), ``drag`` (an effector's phase and target, metres)
and ``export`` (``as`` json or blend); each checked before the driver sees it. Messages:
``rigs`` (the menu), ``scene`` (a rig's layout, camera and rest pose), ``pose`` (each pose
reached: the joints and a mesh rig's surface as points), ``listing`` (the controls most
moved, when a drag ends), ``exported``, ``status`` and ``error``.
"""

from __future__ import annotations

import numpy as np

from rigmap.studio.camera import camera_message, front_camera
from rigmap.studio.page_server import Channel, CommandError, encode
from rigmap.studio.pose_driver import PoseDriver
from rigmap.studio.scene import bone_pairs, to_scene

DRAG_PHASES = ("start", "move", "end")


class PoseChannel(Channel):
    """The Pose page over ``driver``."""

    def __init__(self, driver: PoseDriver):
        super().__init__()
        self.driver = driver
        self._camera = None  # (session, camera) of the rig loaded
        driver.publish = self._published

    def greeting(self) -> list[bytes]:
        session = self.driver.session
        rigs = encode(
            {
                "type": "rigs",
                "names": self.driver.rig_names,
                "current": None if session is None else session.rig.name,
                "status": self.driver.status,
            }
        )
        return [rigs] if session is None else [rigs, self._scene_message()]

    def close(self) -> None:
        self.driver.close()

    def command(self, command: dict) -> None:
        kind = command["type"]
        if kind == "rig":
            name = command.get("name")
            if name not in self.driver.factories:
                raise CommandError(f"rig {name!r}: not one of {', '.join(self.driver.factories)}")
            self.driver.load(name)
        elif kind == "drag":
            self._drag(command)
        elif kind == "export":
            form = command.get("as", "json")
            if form not in ("json", "blend"):
                raise CommandError(f"export as {form!r}: expected json or blend")
            try:
                name = self.driver.export(form)
            except (ValueError, OSError) as error:
                raise CommandError(f"export: {error}") from None
            self.broadcast(encode({"type": "exported", "name": name}))
        else:
            raise CommandError(f"unknown command {kind!r}: expected rig, drag or export")

    def _drag(self, command: dict) -> None:
        phase, target = command.get("phase"), command.get("target")
        if phase not in DRAG_PHASES:
            raise CommandError(f"drag phase {phase!r}: expected one of {DRAG_PHASES}")
        numbers = isinstance(target, list) and len(target) == 3
        if not numbers or any(
            isinstance(v, bool) or not isinstance(v, int | float) for v in target
        ):
            raise CommandError(f"drag target {target!r}: expected [x, y, z] in metres")
        try:
            self.driver.drag(str(command.get("effector")), 100.0 * np.asarray(target), phase=phase)
        except ValueError as error:
            raise CommandError(str(error)) from None
        if phase == "end":
            self.broadcast(encode({"type": "listing", "rows": self.driver.listing()}))

    # ------------------------------------------------------------------ messages
    def _published(self, kind: str, driver: PoseDriver) -> None:
        if kind == "rig":
            self.broadcast(self._scene_message())
            self.broadcast(encode({"type": "listing", "rows": driver.listing()}))
        elif kind == "pose":
            record = driver.record
            header = {"type": "pose", "count": record.count, "status": driver.status}
            self.broadcast(encode(header, self._points(record)), replaceable=True)
        else:
            self.broadcast(encode({"type": "status", "status": driver.status}))

    @staticmethod
    def _points(record) -> np.ndarray:
        parts = [to_scene(record.joints)]
        if record.surface is not None:
            parts.append(to_scene(record.surface))
        return np.concatenate(parts).reshape(-1)

    @property
    def camera(self):
        """The page's camera for the current rig: in front of it at rest (no panel over the
        canvas), the same for every page that opens while the rig is loaded."""
        session = self.driver.session
        if self._camera is None or self._camera[0] is not session:
            record = self.driver.record
            shown = record.surface if record.surface is not None else record.joints
            self._camera = (session, front_camera(to_scene(shown), left_shift=0.0))
        return self._camera[1]

    def _scene_message(self) -> bytes:
        driver = self.driver
        session, record = driver.session, driver.record
        rig = session.rig
        names = list(rig.joint_names)
        faces = getattr(rig, "faces", None) if record.surface is not None else None
        header = {
            "type": "scene",
            "rig": rig.name,
            "status": driver.status,
            "count": record.count,
            "joints": len(names),
            "bones": bone_pairs(rig).tolist(),
            "effectors": list(session.effectors),
            "targets": to_scene(driver.targets).tolist(),
            "vertices": 0 if record.surface is None else len(record.surface),
            "faces": None if faces is None else np.asarray(faces).tolist(),
            "camera": camera_message(self.camera),
        }
        return encode(header, self._points(record))
