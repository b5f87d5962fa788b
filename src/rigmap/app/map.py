"""``rigmap map`` and ``rigmap pose``'s config: ``conf/map.yaml`` composed and made plain for
:mod:`rigmap.map.app`, which takes a plain mapping."""

from __future__ import annotations

from typing import Any

from rigmap.app.objects import plain
from rigmap.app.stage import stage_config


def map_config(overrides: list[str], config_dir=None) -> dict[str, Any]:
    """``conf/map.yaml`` with ``overrides``, the rig's ``_overrides_`` applied, resolved."""
    from rigmap.app.config import compose_config

    return plain(stage_config(compose_config(overrides, config_dir, config_name="map")))
