"""The built-in mesh characters' colours, kept as data in ``palettes.yaml`` beside this module."""

from __future__ import annotations

from importlib import resources

import yaml

PALETTES_FILE = "palettes.yaml"


def palette(character: str) -> dict[str, tuple[float, float, float]]:
    """``character``'s named RGB colours (0..1) from ``PALETTES_FILE``."""
    text = resources.files("rigmap.rigs.characters").joinpath(PALETTES_FILE).read_text("utf-8")
    colours = (yaml.safe_load(text) or {}).get(character)
    if not isinstance(colours, dict):
        raise KeyError(f"{PALETTES_FILE}: no palette for {character!r}")
    for name, rgb in colours.items():
        if not (isinstance(rgb, list) and len(rgb) == 3 and all(0.0 <= c <= 1.0 for c in rgb)):
            raise ValueError(f"{PALETTES_FILE}: {character}.{name} must be [r, g, b] in 0..1")
    return {name: tuple(float(c) for c in rgb) for name, rgb in colours.items()}
