"""The built-in rigs' manifests, one module each (``MANIFEST``); see :mod:`rigmap.rigs.manifest`."""
