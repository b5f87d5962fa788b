"""What the simulation's mapping scores: the rig's mesh against the simulated mesh, the
teeth inside the body in each, and the time per frame.

Per frame (``frames.csv``): the RMS distance over every vertex of the rig's mesh at the
mapped controls from the simulated mesh (cm), the same for the mapping's guess before
refinement, the simulated squirrel's height, and how many teeth vertices lie inside the
body's closed surface in the simulation and in the rig's output. ``summary.json`` holds
their totals, the RMS as a percentage of the rig's rest height (as Table 1's errors), the
mapping's seconds per frame and the settings that made them.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from rigmap.simulation.interpenetration import teeth_inside_body
from rigmap.simulation.vertex_mapping import VertexMapping, vertex_errors
from rigmap.store import json_ready

SUMMARY_FORMAT = "rigmap.simulate/1"


def per_frame(rig, vertices: np.ndarray, mapping: VertexMapping) -> pd.DataFrame:
    """One row per frame (see the module docstring); ``vertices`` ``(F, V, 3)`` world cm."""
    rig_mesh = np.asarray(rig.world_vertices(mapping.controls), dtype=np.float64)
    return pd.DataFrame(
        {
            "frame": np.arange(len(vertices)),
            "vertex_error_cm": np.sqrt(((rig_mesh - vertices) ** 2).sum(axis=2).mean(axis=1)),
            "guess_vertex_error_cm": vertex_errors(rig, mapping.guess, vertices),
            "simulation_height_cm": np.ptp(vertices[:, :, 1], axis=1),
            "teeth_inside_simulation": teeth_inside_body(rig, vertices),
            "teeth_inside_rig": teeth_inside_body(rig, rig_mesh),
        }
    )


def _rms(values) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def _teeth(counts: pd.Series) -> dict:
    return {
        "frames_with_teeth_inside": int((counts > 0).sum()),
        "most_teeth_vertices_inside": int(counts.max()),
        "teeth_vertex_frames_inside": int(counts.sum()),
    }


def summary(rig, frames: pd.DataFrame, mapping: VertexMapping, facts: dict) -> dict:
    """The headline numbers (units in the keys) and ``facts`` (settings, simulation info)."""
    height = float(rig.rest_height())
    rms = _rms(frames["vertex_error_cm"])
    return json_ready(
        {
            "format": SUMMARY_FORMAT,
            "rig": rig.name,
            "frames": len(frames),
            "rig_height_cm": height,
            "vertex_error_rms_cm": rms,
            "vertex_error_rms_percent_of_height": 100.0 * rms / height,
            "vertex_error_max_cm": float(frames["vertex_error_cm"].max()),
            "vertex_error_median_cm": float(frames["vertex_error_cm"].median()),
            "guess_vertex_error_rms_cm": _rms(frames["guess_vertex_error_cm"]),
            "seconds_per_frame": mapping.seconds_per_frame,
            "frames_per_second": 1.0 / mapping.seconds_per_frame,
            "teeth_vertices": len(rig.teeth_vertices),
            "teeth_inside_body": {
                "simulation": _teeth(frames["teeth_inside_simulation"]),
                "rig": _teeth(frames["teeth_inside_rig"]),
            },
            "mapping_seconds": mapping.seconds,
            **facts,
        }
    )
