"""Command scripts for offline animation (Bailey et al. 2016, §5.3, §6: "scripted animations").

A script is YAML: the model to start in, then a list of commands, each a mapping with
one key naming the command::

    start: happy
    commands:
      - move: {take: happy 1, frame: 20}
      - idle: {frames: 48}
      - move: {point: [0.1, -0.4, 0.2], path: graph}
      - transition: {model: roar}
      - play: {take: roar 0}

Errors name the script and the command's position; names of models and takes are
checked when the commands are submitted to a :class:`~rigmap.latent.synthesis.Controller`.
The frames a script asks for (``idle`` frames, a transition's ``idle_frames``) are whole
numbers, together at most ``latent.max_script_frames`` (a cap the controller also keeps).
"""

from __future__ import annotations

import os
from dataclasses import fields
from itertools import accumulate
from pathlib import Path

import yaml

from rigmap.latent.errors import LatentInputError
from rigmap.latent.synthesis import Idle, Move, Play, Transition

COMMANDS = {"move": Move, "idle": Idle, "transition": Transition, "play": Play}
#: ours: the most frames one script may play (about 70 minutes at 24 fps), the default of
#: ``latent.max_script_frames``
MAX_SCRIPT_FRAMES = 100_000
#: ours: the highest ``latent.max_script_frames`` accepted (about 11.5 hours at 24 fps):
#: the controls of every frame are held in memory, so a larger cap could exhaust it
MAX_SCRIPT_FRAMES_LIMIT = 1_000_000
FRAME_COUNTS = ("frames", "idle_frames")  # the arguments that ask for a number of frames


def parse_script(
    data, *, source: str = "script", max_frames: int = MAX_SCRIPT_FRAMES
) -> tuple[str | None, list]:
    """``(start model or None, commands)`` from a parsed YAML mapping; the frames the
    commands ask for are checked against ``max_frames``."""
    if not isinstance(data, dict) or "commands" not in data:
        raise LatentInputError(f"{source}: expected a mapping with a 'commands' list")
    unknown = set(data) - {"start", "commands"}
    if unknown:
        raise LatentInputError(f"{source}: unknown keys {sorted(unknown)}")
    items = data["commands"]
    if not isinstance(items, list) or not items:
        raise LatentInputError(f"{source}: 'commands' must be a non-empty list")
    commands = []
    for k, item in enumerate(items):
        where = f"{source}: command {k + 1}"
        if not isinstance(item, dict) or len(item) != 1:
            raise LatentInputError(
                f"{where}: each command is a one-key mapping, one of {sorted(COMMANDS)}"
            )
        ((name, args),) = item.items()
        kind = COMMANDS.get(str(name).lower())
        if kind is None:
            raise LatentInputError(f"{where}: unknown command {name!r}; one of {sorted(COMMANDS)}")
        args = args if isinstance(args, dict) else {}
        allowed = {f.name for f in fields(kind)}
        bad = set(args) - allowed
        if bad:
            raise LatentInputError(f"{where}: {name} takes {sorted(allowed)}, got {sorted(bad)}")
        for key in FRAME_COUNTS:
            value = args.get(key)
            if key in args and (isinstance(value, bool) or not isinstance(value, int) or value < 0):
                raise LatentInputError(f"{where}: {key} must be a whole number >= 0, got {value!r}")
        if "point" in args and args["point"] is not None:
            args = {**args, "point": tuple(float(v) for v in args["point"])}
        try:
            commands.append(kind(**args))
        except TypeError as error:
            raise LatentInputError(f"{where}: {error}") from None
    check_frame_total(commands, source=source, max_frames=max_frames)
    start = data.get("start")
    return (None if start is None else str(start)), commands


def check_frame_total(commands, *, source: str, max_frames: int) -> None:
    """Refuse, before anything plays, a script whose frames add up past ``max_frames``;
    the message names the command that crosses the cap and the range accepted."""
    totals = list(accumulate(_frames_asked(c) for c in commands))
    asked = totals[-1]
    if asked <= max_frames:
        return
    k = next(i for i, total in enumerate(totals) if total > max_frames)
    command = commands[k]
    raise LatentInputError(
        f"{source}: command {k + 1} ({_describe(command)}) passes the cap: "
        f"the commands ask for {asked} frames, more than latent.max_script_frames={max_frames} "
        f"(accepted: 0 to {max_frames} frames in all, a cap of ours); "
        f"shorten the script or raise the cap (to at most {MAX_SCRIPT_FRAMES_LIMIT})"
    )


def _frames_asked(command) -> int:
    return sum(getattr(command, key, 0) for key in FRAME_COUNTS)


def _describe(command) -> str:
    """``idle frames=48``: a command's name and the frames it asks for, as in the script."""
    name = next(key for key, kind in COMMANDS.items() if isinstance(command, kind))
    asked = [f"{key}={getattr(command, key)}" for key in FRAME_COUNTS if hasattr(command, key)]
    return " ".join([name, *asked])


def read_script(
    path: str | os.PathLike, *, max_frames: int = MAX_SCRIPT_FRAMES
) -> tuple[str | None, list]:
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as error:
        raise LatentInputError(f"cannot read command script {path}: {error}") from None
    return parse_script(data, source=str(path), max_frames=max_frames)
