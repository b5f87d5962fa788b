"""Code that runs inside Blender's own Python (the worker); only ``protocol`` is shared.

The main process imports nothing from here except :mod:`.protocol`; the other
modules import ``bpy`` and are loaded by ``worker.py`` as top-level modules.
"""
