"""A command that must fail with one line: the CLI's exit code 2 and a one-line message."""

from __future__ import annotations


def fails_in_one_line(argv, capsys, *words) -> str:
    """Run ``rigmap argv``; it exits 2 with one line on stderr holding every one of ``words``."""
    from rigmap.cli import main

    assert main(argv) == 2
    message = capsys.readouterr().err.strip()
    assert len(message.splitlines()) == 1, message
    for word in words:
        assert word in message, message
    return message
