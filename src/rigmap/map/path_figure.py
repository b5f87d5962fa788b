"""Fig. 7's figure: a walk bent along a path over terrain, before and after mapping.

Left, the top view: the path, the root's track, and the foot joints' ground positions of
the edited clip (planted frames marked) and of the rig at the mapped controls. Right, the
side view along the path's arc length: the terrain under the root, the feet of the edited
clip and of the rig. Foot skate and penetration of both are in the title.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rigmap.store import atomic_file


def write_path_figure(path: Path, clip, mapped, mapped_names, terrain, scores: dict) -> Path:
    """``path`` (png), atomically: see the module docstring."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    names, feet = list(clip.names), list(clip.contacts.feet)
    figure, (top, side) = plt.subplots(1, 2, figsize=(11, 4.6))
    root = clip.edited[:, clip.root]
    top.plot(root[:, 0], root[:, 2], color="0.4", lw=1, label="root (edited)")
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    arc = np.concatenate(
        [[0.0], np.cumsum(np.linalg.norm(np.diff(root[:, [0, 2]], axis=0), axis=1))]
    )
    side.plot(arc, terrain.height(root[:, 0], root[:, 2]), color="0.3", lw=2, label="terrain")
    for k, foot in enumerate(feet):
        edited = clip.edited[:, names.index(foot)]
        planted = clip.contacts.planted[:, k]
        color = colors[k % len(colors)]
        top.plot(edited[planted, 0], edited[planted, 2], "o", ms=3, color=color, label=foot)
        side.plot(arc, edited[:, 1], color=color, lw=1, label=f"{foot} edited")
        if foot in mapped_names:
            rig = mapped[:, list(mapped_names).index(foot)]
            top.plot(rig[:, 0], rig[:, 2], "-", lw=0.6, color=color)
            side.plot(arc, rig[:, 1], "--", lw=1, color=color, label=f"{foot} rig")
    top.set(xlabel="x (cm)", ylabel="z (cm)", title="top view: plants (dots), rig feet (lines)")
    top.set_aspect("equal", adjustable="datalim")
    top.legend(fontsize=7)
    side.set(xlabel="root arc length (cm)", ylabel="height (cm)", title="side view")
    side.legend(fontsize=6, ncol=2)
    edit, rig = scores["edited"], scores.get("mapped", {})
    figure.suptitle(
        f"skate {edit['foot_skate_cm_per_frame']:.2f} → {rig.get('foot_skate_cm_per_frame', 0):.2f}"
        f" cm/frame, penetration {edit['penetration_max_cm']:.2f} → "
        f"{rig.get('penetration_max_cm', 0):.2f} cm (edited → rig); joint error "
        f"{rig.get('joint_error_rms_cm', 0):.2f} cm RMS",
        fontsize=9,
    )
    figure.tight_layout()
    with atomic_file(path, suffix=".png") as temporary:
        figure.savefig(temporary, dpi=110, format="png")
    plt.close(figure)
    return path
