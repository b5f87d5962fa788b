"""The Play page's side in Python: a :class:`PlaySession` behind its websocket.

Commands: ``transition`` (a model), ``play`` (a take), ``move`` (a take's frame), ``idle``
(a number of frames), ``cell`` (X on cell 0-8) and ``new_game``; each checked before the
session sees it. Messages: ``scene`` (the face's triangles, the camera, the models),
``frame`` (each frame's vertices at its deadline) and ``state`` (the status lines, the
board, the takes the next command may name). The stream runs while a Play page is open.
"""

from __future__ import annotations

import threading

import numpy as np

from rigmap.latent.synthesis import Idle, Move, Play, Transition
from rigmap.studio.camera import camera_message, front_camera
from rigmap.studio.page_server import Channel, CommandError, encode
from rigmap.studio.play_session import IDLE_FRAMES, PlaySession


class PlayChannel(Channel):
    """The Play page over ``session``."""

    def __init__(self, session: PlaySession):
        super().__init__()
        self.session = session
        self.camera = front_camera(session.vertices, left_shift=0.0)
        self._pages = 0
        self._pages_lock = threading.Lock()
        session.publish = self._published

    def greeting(self) -> list[bytes]:
        session = self.session
        header = {
            "type": "scene",
            "faces": np.asarray(session.rig.faces).tolist(),
            "vertices": len(session.vertices),
            "camera": camera_message(self.camera),
            "models": list(session.fitted.models),
            "idle_frames": IDLE_FRAMES,
        }
        return [encode(header, session.vertices), self._state()]

    def opened(self) -> None:
        with self._pages_lock:
            self._pages += 1
            self.session.show(True)

    def closed(self) -> None:
        with self._pages_lock:
            self._pages -= 1
            if self._pages == 0:
                self.session.show(False)

    def close(self) -> None:
        self.session.close()

    def command(self, command: dict) -> None:
        session, kind = self.session, command["type"]
        if kind == "transition":
            session.command(Transition(_text(command, "model")))
        elif kind == "play":
            session.command(Play(_text(command, "take")))
        elif kind == "move":
            session.command(Move(take=_text(command, "take"), frame=_count(command, "frame", 0)))
        elif kind == "idle":
            session.command(Idle(_count(command, "frames", 1)))
        elif kind == "cell":
            cell = _count(command, "cell", 0)
            if cell > 8:
                raise CommandError(f"cell {cell}: expected 0-8 (reading order)")
            session.click_cell(cell)
        elif kind == "new_game":
            session.new_game()
        else:
            raise CommandError(
                f"unknown command {kind!r}: expected transition, play, move, idle, cell or new_game"
            )

    # ------------------------------------------------------------------ messages
    def _published(self, kind: str, session: PlaySession) -> None:
        if kind == "frame":
            frame = encode({"type": "frame", "frame": session.frame}, session.vertices)
            self.broadcast(frame, replaceable=True)
        else:
            self.broadcast(self._state())

    def _state(self) -> bytes:
        session = self.session
        return encode(
            {
                "type": "state",
                "status": session.status(),
                "cells": session.cell_labels(),
                "game": session.game_state(),
                "over": session.board.over,
                "takes": session.take_names(),
            }
        )


def _text(command: dict, key: str) -> str:
    value = command.get(key)
    if not isinstance(value, str) or not value:
        raise CommandError(f"{command['type']}: {key} must be a name, got {value!r}")
    return value


def _count(command: dict, key: str, least: int) -> int:
    value = command.get(key)
    if isinstance(value, bool) or not isinstance(value, int) or value < least:
        raise CommandError(f"{command['type']}: {key} must be an integer >= {least}, got {value!r}")
    return value
