"""``rigmap studio``: the browser studio (:mod:`rigmap.studio`) from the shell.

This module is the only studio code that reads config: it composes ``conf/map.yaml`` per
rig (the same options as ``rigmap pose``) and hands the pages plain objects: for the Pose
page one :class:`~rigmap.studio.pose_driver.PoseSession` factory per rig, built when the user
picks the rig (its effector mapping read from the cache, or fitted on the pipeline's
corpus the first time).
"""

from __future__ import annotations

import sys
from pathlib import Path

from rigmap.app.arguments import override_arguments

#: the built-in rigs the Pose page offers (Fig 5 full-body IK, Fig 6 feet, Fig 10 FaceIK)
POSE_RIGS = ("biped", "quadruped", "face")
#: ours: one damped step per drag event (9 ms on the biped against 26 for rigmap pose's two;
#: the page sends every move and the next pose refines further); map.drag.steps= changes it
STUDIO_DEFAULTS = ("map.drag.steps=1",)
#: the rig the Play view drives: the keyed face, whose labels are the game's emotions
PLAY_RIG = "face"


def add_studio_command(commands, compose_config, find_config_dir) -> None:
    studio = commands.add_parser(
        "studio",
        help="pose, review, edit and play in the browser (a local web app)",
        description="Serves rigmap's interactive tools as local web pages on 127.0.0.1 unless "
        "--host says otherwise. Pose (its own WebGL page, --pages-port): drag a rig's "
        "effectors and the partial-input mapping with refinement poses the rig (biped: full "
        "body, quadruped, face: FaceIK), using the corpus the main job wrote (data/) and the "
        "map's cached models; export the pose as JSON. Play (its own page, when the face's "
        "latent models exist: rigmap synth, or the main job's): the face driven live at 24 "
        "fps by MOVE / IDLE / TRANSITION / PLAY buttons and by a game of noughts and crosses "
        "against you. Review and Edit (viser's three.js page, --port): a `rigmap map` output "
        "folder under --folder played back, the source beside the rig, with its per-frame "
        "error, confidence, keys and foot contacts; a BVH under --folder, frames, joints "
        "dragged with pins (the IK), the edit learned, applied to another clip and fixed (the "
        "`rigmap edits learn/apply/fix` calls). Reads files only under --folder, writes only "
        "under --out. Example: rigmap studio, then open http://127.0.0.1:8081 (Pose) or "
        "http://127.0.0.1:8080 (Review, Edit).",
    )
    studio.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    studio.add_argument(
        "--port",
        type=int,
        default=8080,
        help="the Review and Edit page's port (default 8080; 0: any free)",
    )
    studio.add_argument(
        "--pages-port",
        type=int,
        default=8081,
        help="the port of the studio's own Pose and Play pages (default 8081; 0: any free)",
    )
    studio.add_argument(
        "--folder",
        type=Path,
        default=Path("."),
        help="the only folder the studio reads files from (default: the working directory)",
    )
    studio.add_argument(
        "--out",
        type=Path,
        default=None,
        help="the only folder it writes to (default: outputs/studio)",
    )
    studio.add_argument(
        "--rigs",
        default=",".join(POSE_RIGS),
        help=f"rigs the Pose page offers, comma-separated (default {','.join(POSE_RIGS)})",
    )
    override_arguments(studio, "map", "for every rig: paths.data=, map.drag.steps=, ...")
    studio.set_defaults(run=lambda args: _serve(args, find_config_dir))


def _serve(args, find_config_dir) -> int:
    studio = build_studio(
        rigs=[r for r in args.rigs.split(",") if r],
        overrides=list(args.overrides),
        config_dir=find_config_dir(args.config_dir),
        folder=args.folder,
        out=args.out,
        host=args.host,
        port=args.port,
        pages_port=args.pages_port,
    )
    links = " and ".join(f"{url} ({name})" for name, url in studio.pages.links().items())
    print(f"rigmap studio: {studio.url} (Review, Edit), {links}; Ctrl-C stops it", flush=True)
    studio.wait()
    return 0


def build_studio(*, rigs, overrides, config_dir, folder, out=None, host, port, pages_port=0):
    """The studio with its views, serving at ``host:port``, and its own pages (Pose, Play)
    at ``host:pages_port`` (a port 0: a free one)."""
    from rigmap.app.edits import load_settings
    from rigmap.rigs import load
    from rigmap.store import Layout
    from rigmap.studio.app import Studio
    from rigmap.studio.edit_view import EditView
    from rigmap.studio.page_server import PageServer
    from rigmap.studio.play_page import PlayChannel
    from rigmap.studio.pose_driver import PoseDriver
    from rigmap.studio.pose_page import PoseChannel
    from rigmap.studio.review_view import ReviewView
    from rigmap.studio.served_folder import ServedFolder
    from rigmap.studio.writes import OutputFolder

    served = ServedFolder(folder)  # checked before the port opens
    unknown = [r for r in rigs if not r.strip()]
    if unknown or not rigs:
        raise ValueError(f"--rigs: expected rig names separated by commas, got {rigs!r}")
    output = OutputFolder(out if out is not None else Layout.user_output("studio"))
    factories = {rig: _pose_factory(rig, overrides, config_dir) for rig in rigs}
    driver = PoseDriver(factories, output)
    driver.load(rigs[0])
    views = [
        ReviewView(served, load),
        EditView(served, output, load_settings(config_dir)),
    ]
    channels = {"pose": PoseChannel(driver)}
    try:
        channels["play"] = PlayChannel(play_session(overrides, config_dir))
    except FileNotFoundError as missing:  # no latent models yet: the other pages still serve
        print(f"rigmap studio: no Play page: {missing}", file=sys.stderr, flush=True)
    try:
        pages = PageServer(channels, host=host, port=pages_port)
    except OSError as error:  # the port is taken, or the address is not this machine's
        for channel in channels.values():
            channel.close()
        reason = error.strerror or error
        raise ValueError(f"--pages-port {pages_port}: cannot serve on {host}: {reason}") from None
    try:
        studio = Studio(views, host=host, port=port, pages=pages)
    except BaseException:
        pages.stop()
        raise
    pages.studio_url = studio.url
    return studio


def play_session(overrides, config_dir, rig_name: str = PLAY_RIG):
    """Play on ``rig_name``'s latent models: your own ``rigmap synth fit`` and ``match``
    (under outputs/) when there, else the pipeline's (``models/``)."""
    from rigmap.app.config import compose_config
    from rigmap.app.inputs import layout_of
    from rigmap.app.latent import fitted_models_config
    from rigmap.latent import steps
    from rigmap.rigs import load
    from rigmap.studio.play_session import PlaySession

    paths = [o for o in overrides if o.partition("=")[0].lstrip("+~").startswith("paths.")]
    cfg = fitted_models_config([f"rig={rig_name}", *paths], config_dir, compose_config)
    layout = layout_of(cfg)
    fitted, table = steps.load_fitted(layout, rig_name), steps.load_table(layout, rig_name)
    return PlaySession(load(rig_name), fitted, table)


def _pose_factory(rig_name: str, overrides, config_dir):
    def build():
        return pose_session(rig_name, overrides, config_dir)

    return build


def pose_session(rig_name: str, overrides, config_dir):
    """A :class:`PoseSession` of ``rig_name`` from ``conf/map.yaml`` and ``overrides``."""
    from rigmap.app.map_job import interactive_poser, map_config, posing_parts, rig_options
    from rigmap.rigs import load
    from rigmap.studio.pose_driver import PoseSession
    from rigmap.user_outputs import user_paths

    given = {o.partition("=")[0] for o in overrides}
    defaults = [d for d in STUDIO_DEFAULTS if d.partition("=")[0] not in given]
    overrides = [f"rig={rig_name}", *user_paths(overrides, keys=("models",)), *defaults, *overrides]
    config = map_config(overrides, config_dir)
    rig = load(rig_options(config))
    subset, model, settings = posing_parts(config, rig, log=lambda _line: None)
    poser = interactive_poser(rig, model, settings, config["map"].get("drag"))

    def pose(targets):
        result = poser(targets)
        return result.controls, result.distance_cm, result.joints

    return PoseSession(
        rig=rig,
        effectors=tuple(subset.joints),
        pose=pose,
        reset=poser.reset,
        rest=rig.controls.defaults.astype("float64").copy(),
        description=f"{subset.name}: {len(subset.joints)} effectors",
    )
