"""Resuming after a kill never mixes in work of another rig version (issue 20, defect 2)."""

from __future__ import annotations

import numpy as np
import pytest

from rigmap.sampling import PCAGaussianSampler
from rigmap.sampling.supersample import _rig_fingerprint, load_samples
from test_supersample import N_CHUNKS, Killed, WatchedRig, quadruped_corpus, run

MOVED_JOINT = 5
OFFSET_CM = 0.5


class MovedJointRig(WatchedRig):
    """The same rig (same name, controls, joints) whose joint 5 sits 0.5 cm further along x:
    what a rig code change to one joint offset does."""

    def _moved(self, positions):
        positions = np.array(positions, dtype=np.float64, copy=True)
        positions[:, MOVED_JOINT, 0] += OFFSET_CM
        return positions

    def evaluate(self, Y):
        return self._moved(self._rig.evaluate(Y))

    def pose(self, Y):
        pose = super().pose(Y)
        return pose._replace(positions=self._moved(pose.positions))


@pytest.fixture(scope="module")
def sampler(quadruped):
    return PCAGaussianSampler().fit(quadruped_corpus(quadruped))


def test_fingerprint_covers_behaviour_not_only_names(quadruped):
    assert _rig_fingerprint(quadruped) == _rig_fingerprint(WatchedRig(quadruped))
    assert _rig_fingerprint(MovedJointRig(quadruped)) != _rig_fingerprint(quadruped)


def test_chunks_posed_by_an_older_rig_version_are_not_reused(quadruped, sampler, tmp_path):
    """Defect 2: after a rig change, a resumed supersample reused the old version's chunks."""
    killed = WatchedRig(quadruped, fail_after=2)  # the old rig dies after two chunks
    with pytest.raises(Killed):
        run(killed, sampler, tmp_path / "resumed")
    assert len(list((tmp_path / "resumed" / "pca_gaussian.chunks").glob("*.npz"))) == 2

    changed = MovedJointRig(quadruped)  # the rig's code changed before the resume
    result = run(changed, sampler, tmp_path / "resumed")
    assert changed.calls == N_CHUNKS and result.chunks_resumed == 0  # every chunk re-posed

    fresh = MovedJointRig(quadruped)
    run(fresh, sampler, tmp_path / "fresh")
    resumed = (tmp_path / "resumed" / "pca_gaussian.npz").read_bytes()
    assert resumed == (tmp_path / "fresh" / "pca_gaussian.npz").read_bytes()
    samples = load_samples(tmp_path / "resumed" / "pca_gaussian.npz")
    expected = changed.evaluate(quadruped.expand_used(samples["controls"]))
    np.testing.assert_allclose(samples["positions"], expected, rtol=0, atol=1e-9)
