"""Reusable rig feature units (like Rigify's): each owns its controls and mechanics.

A unit is a function that takes a :class:`~rigmap.rigs.engine.builder.RigBuilder`,
creates its control channels and appends evaluation steps that write world
transforms of joints. Characters are assembled from these units.
"""
