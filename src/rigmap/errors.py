"""The one base of the errors rigmap raises on purpose.

A ``RigmapError`` means bad input, a bad config or a missing environment: something the
user can fix from the message alone. Entry points print it as one message and exit
non-zero; any other exception is a bug and keeps its traceback. Each error class also
keeps its builtin base (``ValueError``, ``RuntimeError`` …) so existing handlers work.
"""

from __future__ import annotations


class RigmapError(Exception):
    """An error with a message meant for the user (file, field, what to do)."""
