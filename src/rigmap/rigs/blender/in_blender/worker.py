"""A Blender worker: answers rigmap's requests, one frame in, one frame out.

Started by the main process as either
    <blender venv>/bin/python worker.py [--pin-cpu N]
or  blender -b --factory-startup --python worker.py -- [--pin-cpu N]

The protocol runs on the original stdin/stdout; this process first moves them
to private descriptors and points fd 1 at stderr, so anything Blender or a
script prints lands in the log, never inside a frame. The worker exits when its
input ends (the parent closed the pipe or died).
"""

from __future__ import annotations

import os
import sys
import threading
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))


def claim_stdio() -> tuple[int, int]:
    """Private protocol descriptors; fd 0 becomes /dev/null and fd 1 a copy of stderr."""
    in_fd, out_fd = os.dup(0), os.dup(1)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.close(devnull)
    sys.stdout.flush()
    os.dup2(2, 1)
    return in_fd, out_fd


def die_with_parent(poll_seconds: float = 1.0) -> None:
    """Exit when the parent process goes away, even in the middle of a long request.

    (Not prctl's PDEATHSIG: that fires when the parent *thread* that started the
    worker ends, and rigmap starts workers from short-lived pool threads.)
    """
    parent = os.getppid()

    def watch() -> None:
        while True:
            time.sleep(poll_seconds)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def parse_args(argv: list[str]) -> dict:
    args = argv[argv.index("--") + 1 :] if "--" in argv else argv[1:]
    options = {"pin_cpu": None}
    if "--pin-cpu" in args:
        options["pin_cpu"] = int(args[args.index("--pin-cpu") + 1])
    return options


class Channel:
    def __init__(self, in_fd: int, out_fd: int):
        self.in_fd, self.out_fd = in_fd, out_fd

    def read_exact(self, n: int) -> bytes:
        chunks, remaining = [], n
        while remaining:
            chunk = os.read(self.in_fd, min(remaining, 1 << 24))
            if not chunk:
                break
            chunks.append(chunk)
            remaining -= len(chunk)
        return b"".join(chunks)

    def send(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            written = os.write(self.out_fd, view)
            view = view[written:]


class Worker:
    """Holds the open rig session and dispatches requests to it."""

    def __init__(self):
        self.session = None

    def handle(self, op: str, args: dict, arrays: dict) -> tuple[dict, dict]:
        handler = getattr(self, f"op_{op}", None)
        if handler is None:
            raise ValueError(f"unknown operation {op!r}")
        return handler(args, arrays)

    def _session(self):
        if self.session is None:
            raise RuntimeError("no rig loaded: send 'load' first")
        return self.session

    def op_ping(self, args, arrays):
        return {}, {}

    def op_load(self, args, arrays):
        from rig_session import RigSession

        self.session = None
        self.session = RigSession(args["options"])
        return {"description": self.session.description()}, {}

    def op_describe(self, args, arrays):
        return {"description": self._session().description()}, {}

    def op_evaluate(self, args, arrays):
        start = time.process_time()  # this process's CPU, Blender's threads included
        out = self._session().evaluate(arrays["controls"])
        return {"cpu_seconds": time.process_time() - start}, out

    def op_set_controls(self, args, arrays):
        self._session().apply(arrays["controls"])
        return {}, {}

    def op_read_controls(self, args, arrays):
        return {}, {"controls": self._session().read_controls()}

    def op_play(self, args, arrays):
        import numpy as np
        from keyframes import play

        session = self._session()
        frames = arrays.get("frames")
        if frames is None:  # the file's frame range
            scene = session.scene
            frames = np.arange(scene.frame_start, scene.frame_end + 1, dtype=np.float64)
        return {}, {"frames": frames, **play(session, frames)}

    def op_export(self, args, arrays):
        from keyframes import save_blend, write_keyframes

        info = write_keyframes(
            self._session(),
            arrays["frames"],
            arrays["values"],
            args["names"],
            args["action"],
            args.get("fps"),
        )
        save_blend(args["out_path"])
        return info, {}

    def op_retarget(self, args, arrays):
        from retarget import constraint_retarget

        controls = constraint_retarget(
            self._session(),
            arrays["positions"],
            arrays["cog"],
            arrays["cog_rotation"],
            args["mapping"],
        )
        return {}, {"controls": controls}

    def op_read_actions(self, args, arrays):
        from blend_actions import frame_dependence, open_session, read_actions

        self.session = None
        self.session = open_session(args["options"])
        info = read_actions(self.session, args.get("actions", "*"))
        info["frame_dependence"] = frame_dependence(self.session)
        animation = self.session.rig.animation_data
        if animation is not None:  # later requests evaluate controls, not the keys
            animation.action = None
            animation.use_nla = False
        return info, {}

    def op_write_actions(self, args, arrays):
        from blend_actions import write_actions
        from keyframes import save_blend

        info = write_actions(
            self._session(), args["clips"], args.get("fps"), bool(args.get("scene_range"))
        )
        save_blend(args["out_path"])
        return info, {}

    def op_write_shape_keys(self, args, arrays):
        from keyframes import save_blend
        from shape_keys import write_shape_keys

        self.session = None  # the scene is replaced by an empty one
        info = write_shape_keys(
            args["object"],
            arrays["rest"],
            arrays["triangles"],
            arrays["shapes"],
            args["names"],
            arrays["frames"],
            arrays["weights"],
            args["action"],
            float(args["fps"]),
        )
        save_blend(args["out_path"])
        return info, {}

    def op_read_shape_keys(self, args, arrays):
        from shape_keys import read_shape_keys

        self.session = None  # the file replaces whatever was open
        return read_shape_keys(args["path"], args.get("vertices_at"))

    def op_simulate_soft_body(self, args, arrays):
        from softbody import simulate

        self.session = None  # the scene is replaced by the simulation's
        parts = (arrays[k] for k in ("rest", "triangles", "springs", "pinned"))
        return simulate(*parts, args["scenario"])

    def op_generate_rigify(self, args, arrays):
        from rigify_generate import generate

        self.session = None
        info = generate(
            args["metarig"], args["out_path"], args["euler_order"], args["exclude_bones"]
        )
        return info, {}


def main() -> int:
    in_fd, out_fd = claim_stdio()
    die_with_parent()
    options = parse_args(sys.argv)
    if options["pin_cpu"] is not None and hasattr(os, "sched_setaffinity"):
        cpus = sorted(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpus[options["pin_cpu"] % len(cpus)]})  # before bpy starts threads
    sys.path.insert(0, HERE)
    import bpy
    import numpy
    import protocol

    channel = Channel(in_fd, out_fd)
    hello = {
        "op": "hello",
        "protocol": protocol.PROTOCOL_VERSION,
        "pid": os.getpid(),
        "blender_version": bpy.app.version_string,
        "python": sys.version.split()[0],
        "numpy": numpy.__version__,
    }
    channel.send(protocol.encode_frame(hello))
    worker = Worker()
    while True:
        frame = protocol.read_frame(channel.read_exact)
        if frame is None:
            return 0
        header, arrays = frame
        op = header.get("op", "")
        if op == "exit":
            channel.send(protocol.encode_frame({"ok": True}))
            return 0
        try:
            reply, out = worker.handle(op, header.get("args", {}), arrays)
            message = protocol.encode_frame({"ok": True, **reply}, out)
        except Exception as error:  # reported to the caller, the worker stays up
            message = protocol.encode_frame(
                {
                    "ok": False,
                    "error": f"{type(error).__name__}: {error}",
                    "traceback": traceback.format_exc(),
                }
            )
        channel.send(message)


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)  # skip Blender's atexit teardown; nothing is left to save
