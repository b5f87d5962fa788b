"""rigmap: learning inverse rig mappings (Holden, Saito & Komura, TVCG 2017)."""

__version__ = "0.1.0"
