"""``executor=ray``: Blender workers as Ray actors on a local head (127.0.0.1, 2 CPUs).

The pool's sharding, ordering and recovery are checked against the stand-in worker of
``test_blender_pool`` (same protocol, a known function of each row); the last test poses
the Rigify wolf through Ray and the local pool and compares the bytes.
"""

from __future__ import annotations

import os
import signal
import socket
import sys

import numpy as np
import pytest

from rigmap.rigs.blender.pool import WorkerPool
from rigmap.rigs.blender.ray_pool import RayUnavailableError, RayWorkerPool, ensure_ray
from rigmap.rigs.blender.worker_process import WorkerError
from test_blender_pool import PROTOCOL_DIR, STAND_IN


@pytest.fixture(scope="session")
def ray_head():
    """One local Ray head for the session: 127.0.0.1, 2 CPUs, no dashboard."""
    import ray

    ray.init(
        address="local",
        num_cpus=2,
        include_dashboard=False,
        log_to_driver=False,
        _node_ip_address="127.0.0.1",
    )
    yield ray
    ray.shutdown()


@pytest.fixture
def stand_in(tmp_path):
    script = tmp_path / "stand_in.py"
    script.write_text(STAND_IN)

    def argv(*flags):
        return lambda _slot: [sys.executable, str(script), str(PROTOCOL_DIR), *flags]

    return argv


def ray_pool(stand_in, tmp_path, **kwargs):
    kwargs.setdefault("actors", 2)
    return RayWorkerPool(
        stand_in(), setup=[("load", {"offset": 0.5})], log_dir=tmp_path / "logs", **kwargs
    )


def test_ray_actors_give_the_local_pools_bytes_sharded_by_row(ray_head, stand_in, tmp_path):
    Y = np.random.default_rng(0).normal(size=(37, 4))
    with WorkerPool(
        stand_in(), setup=[("load", {"offset": 0.5})], workers=2, log_dir=tmp_path / "logs"
    ) as local:
        expected = local.map_rows("evaluate", {"controls": Y}, chunk_rows=5)["positions"]
    with ray_pool(stand_in, tmp_path) as pool:
        done = []
        out = pool.map_rows("evaluate", {"controls": Y}, chunk_rows=5, on_chunk_done=done.append)
        assert pool.setup_replies == [{"ok": True, "loaded": 0.5}]
        worker_pids = set(out["pid"].tolist())
    assert out["positions"].tobytes() == expected.tobytes()
    assert sum(done) == 37 and len(done) == 8  # 5-row chunks, as the local pool cuts them
    assert len(worker_pids) == 2  # both actors' workers took chunks


def test_actor_lost_mid_batch_is_redone_on_another(ray_head, stand_in, tmp_path):
    Y = np.random.default_rng(1).normal(size=(40, 3))
    killed = []
    with ray_pool(stand_in, tmp_path) as pool:
        reference = pool.map_rows("evaluate", {"controls": Y}, chunk_rows=4)["positions"]
        victim = pool._actors[0]

        def kill_once(_rows):  # the first chunk back: the victim still holds queued chunks
            if not killed:
                ray_head.kill(victim)
                killed.append(victim)

        again = pool.map_rows(
            "evaluate",
            {"controls": Y},
            args={"delay": 0.05},
            chunk_rows=4,
            on_chunk_done=kill_once,
        )
        assert killed and pool.restarts >= 1 and pool._actors[0] is not victim
    assert again["positions"].tobytes() == reference.tobytes()


def test_blender_worker_crash_inside_an_actor_is_retried(ray_head, stand_in, tmp_path):
    Y = np.arange(24.0).reshape(12, 2)
    with ray_pool(stand_in, tmp_path) as pool:
        pool.start()
        os.kill(pool.actor_info[1]["pid"], signal.SIGKILL)  # the Blender process, not the actor
        out = pool.map_rows("evaluate", {"controls": Y}, chunk_rows=2)
        assert pool.restarts >= 1
    assert np.array_equal(out["positions"], Y * 2.0 + 0.5)


def test_an_error_inside_the_worker_is_raised_not_retried(ray_head, stand_in, tmp_path):
    with ray_pool(stand_in, tmp_path) as pool:
        with pytest.raises(WorkerError, match="unknown operation 'frobnicate'"):
            pool.map_rows("frobnicate", {"controls": np.ones((4, 2))})
        assert pool.restarts == 0


def test_no_ray_cluster_at_the_address_is_a_clear_error(monkeypatch):
    import ray

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]  # closed again: nothing listens there
    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    with pytest.raises(RayUnavailableError, match=rf"no Ray cluster answers at 127.0.0.1:{port}"):
        ensure_ray(f"127.0.0.1:{port}")
    with pytest.raises(RayUnavailableError, match="not host:port"):
        ensure_ray("nonsense")


def test_ray_not_installed_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(RayUnavailableError, match=r"needs the ray package.*\.\[scale\]"):
        ensure_ray()


def test_executor_choice_is_checked_and_only_blender_rigs_take_ray(quadruped):
    from rigmap.errors import RigmapError
    from rigmap.rigs import use_executor
    from rigmap.rigs.base import RigInputError
    from rigmap.rigs.blender.rig import executor_options

    assert executor_options(None, "w") == {"kind": "local"}
    assert executor_options({"kind": "ray", "address": None, "actors": 2}, "w")["actors"] == 2
    with pytest.raises(RigInputError, match="executor kind must be one of"):
        executor_options("dask", "w")
    with pytest.raises(RigInputError, match=r"takes \['kind'\], not \['actors'\]"):
        executor_options({"kind": "local", "actors": 2}, "w")
    with pytest.raises(RigmapError, match="rig 'quadruped' is evaluated in this process"):
        use_executor(quadruped, {"kind": "ray"})
    assert use_executor(quadruped, {"kind": "local"}) is quadruped


def test_executor_group_composes():
    from hydra import compose, initialize_config_dir

    from rigmap.store.layout import find_project_root

    conf = find_project_root() / "conf"
    with initialize_config_dir(str(conf), version_base=None):
        assert compose("config").executor == {"kind": "local"}
        ray_cfg = compose("config", overrides=["executor=ray", "executor.actors=2"]).executor
    assert ray_cfg.kind == "ray" and ray_cfg.actors == 2 and ray_cfg.address is None


@pytest.mark.blender
def test_wolf_through_ray_is_byte_identical_to_the_local_pool(ray_head):
    from rigmap.rigs.blender.rigify import build_rigify_wolf

    with build_rigify_wolf(workers=2) as wolf:
        used = wolf.controls.used_indices
        rng = np.random.default_rng(3)
        Y = wolf.default_controls(70)
        lower, upper = wolf.controls.lower[used], wolf.controls.upper[used]
        Y[:, used] = lower + (upper - lower) * rng.uniform(0.3, 0.7, size=(70, len(used)))
        local = wolf.pose(Y)
        wolf.use_executor({"kind": "ray", "actors": 2})
        remote = wolf.pose(Y)
        assert type(wolf.pool).__name__ == "RayWorkerPool"
    for a, b in zip(local, remote, strict=True):
        assert a.tobytes() == b.tobytes()
