"""The default DVC remote: its check names the remote and what to do when it is missing."""

from __future__ import annotations

from pathlib import Path

import pytest

from rigmap.dvc_remote import RemoteUnavailableError, check_remote, main

REPO = Path(__file__).resolve().parents[1]


def project(tmp_path: Path, url: str | None) -> Path:
    root = tmp_path / "clone"
    (root / ".dvc").mkdir(parents=True)
    text = "[core]\n    analytics = false\n"
    if url is not None:
        text += f"    remote = shared\n['remote \"shared\"']\n    url = {url}\n"
    (root / ".dvc" / "config").write_text(text.replace("'", ""))
    return root


def test_the_repositorys_default_remote_is_a_folder_beside_the_clone():
    from rigmap.dvc_remote import default_remote

    assert default_remote(REPO) == ("shared", "../../rigmap-dvc-remote")


def test_missing_local_remote_is_a_clear_error_for_pull_but_fine_for_push(tmp_path):
    root = project(tmp_path, "../../rigmap-dvc-remote")
    with pytest.raises(
        RemoteUnavailableError, match=r"'shared' .* does not exist: nothing to pull"
    ):
        check_remote(root, "pull")
    assert check_remote(root, "push") == tmp_path / "rigmap-dvc-remote"  # push creates it
    (tmp_path / "rigmap-dvc-remote").mkdir()
    assert check_remote(root, "pull") == tmp_path / "rigmap-dvc-remote"


def test_no_default_remote_and_the_command_line(tmp_path, monkeypatch, capsys):
    root = project(tmp_path, None)
    with pytest.raises(RemoteUnavailableError, match="no default DVC remote"):
        check_remote(root, "pull")
    monkeypatch.chdir(root)
    assert main(["check", "pull"]) == 1
    assert "dvc remote add -d shared" in capsys.readouterr().err
    assert main(["check", "fetch"]) == 2
