"""Particle synthesis (Bailey et al. 2016 §5.1) and the commands (§5.3) on the face's models."""

from __future__ import annotations

import numpy as np
import pytest

from latent_face import face_models, face_rig, face_transitions
from rigmap.latent import LatentInputError
from rigmap.latent.particle import LatentField, Particle, ParticleSettings, RandomForce
from rigmap.latent.synthesis import Controller, Idle, Move, Play, Transition


@pytest.fixture(scope="module")
def fitted():
    return face_models()


def controller(fitted, seed=0, start="happy", **kw):
    return Controller(
        fitted.models,
        start=start,
        takes=fitted.sets,
        transitions=face_transitions(),
        seed=seed,
        **kw,
    )


def test_field_controls_match_the_model(fitted):
    model = fitted.models["roar"]
    field = LatentField(model)
    X = model.latent[::17] + 0.05
    expected = model.to_controls(X)
    got = np.array([field.controls(x) for x in X])
    np.testing.assert_allclose(got, expected, atol=1e-9)


def test_confidence_gradient_matches_finite_differences(fitted):
    model = fitted.models["happy"]
    field = LatentField(model)
    var = model.gplvm.variance(model.latent[:3] + 0.3)
    for k, x in enumerate(model.latent[:3] + 0.3):
        c, grad = field.confidence_and_gradient(x)
        assert c == pytest.approx(1.0 - var[k] / model.gplvm.kernel_variance, abs=1e-9)
        eps = 1e-5
        numeric = [
            (field.confidence(x + eps * e) - field.confidence(x - eps * e)) / (2 * eps)
            for e in np.eye(len(x))
        ]
        np.testing.assert_allclose(grad, numeric, rtol=1e-4, atol=1e-9)


def test_random_force_has_the_kernels_covariance():
    """Over many seeds the draws' covariance at lag Δt is α_r exp(−Δt²/2γ)."""
    s = ParticleSettings(random_variance=0.5, random_timescale_s=0.3, random_features=64)
    lags = np.array([0.0, 0.1, 0.3, 0.6])
    draws = np.array([[RandomForce(2, s, seed)(1.7 + lag) for lag in lags] for seed in range(3000)])
    a = draws[:, :, 0]
    cov = (a * a[:, :1]).mean(0)
    expected = 0.5 * np.exp(-(lags**2) / (2 * 0.3**2))
    np.testing.assert_allclose(cov, expected, atol=0.04)


def test_free_particle_moves_at_constant_velocity(fitted):
    """No forces (no random force, drag or probability force) and a path far away: RK4
    carries the particle straight on."""
    s = ParticleSettings(random_variance=0.0, drag=0.0, probability_force=0.0, radius=100.0)
    field = LatentField(fitted.models["happy"])
    p = Particle(field, np.zeros(3), settings=s, v0=[0.24, 0.0, -0.48])
    for _ in range(24):
        p.step(np.full(3, 50.0), np.full(3, 50.0))
    np.testing.assert_allclose(p.x, [0.24, 0.0, -0.48], atol=1e-12)


def test_constraint_pulls_an_outside_particle_back_within_r(fitted):
    field = LatentField(fitted.models["happy"])
    s = ParticleSettings(radius=0.1)
    centre = field.X[10]
    p = Particle(field, centre + np.array([0.5, 0.0, 0.0]), settings=s, seed=3)
    distances = []
    for _ in range(48):
        p.step(centre, centre)
        distances.append(np.linalg.norm(p.x - centre))
        assert p.last_lambda <= 0.0  # the force only ever points towards the path
    assert distances[0] > 0.4
    assert max(distances[24:]) <= 0.1 * 1.01


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_idle_keeps_the_particle_within_r(fitted, seed):
    c = controller(fitted, seed=seed)
    c.run([Move(take="happy 1", frame=20)])
    centre = c.anchor.copy()
    c.submit(Idle(120))
    worst = 0.0
    while c.busy:
        c.step()
        worst = max(worst, float(np.linalg.norm(c.particle.x - centre)))
    r = c.settings.particle.radius
    assert worst <= 1.02 * r
    assert worst > 0.2 * r  # it does move about: the random force is on
    assert c.log[-1].success


def script():
    return [
        Move(take="happy 1", frame=15),
        Idle(36),
        Move(take="happy 0", frame=30, path="graph"),
        Idle(24),
    ]


def test_repeats_of_one_script_differ_a_little(fitted):
    runs = [controller(fitted, seed=seed).run(script()) for seed in (0, 1, 2)]
    again = controller(fitted, seed=0).run(script())
    np.testing.assert_array_equal(runs[0], again)  # a seed is a seed
    rig = face_rig()
    train = fitted.sets["happy"].values
    spread = float(np.sqrt(((train - train.mean(0)) ** 2).sum(1).mean()))
    for a in range(3):
        for b in range(a + 1, 3):
            # each pose of one run against the nearest pose of the other: timing aside
            D = np.sqrt(((runs[a][:, None] - runs[b][None]) ** 2).sum(-1)).min(1)
            assert D.max() > 1e-3  # they differ
            assert D.mean() < 0.1 * spread  # a little: well inside the set's own spread
    for run in runs:
        assert (run >= rig.controls.lower).all() and (run <= rig.controls.upper).all()


def test_move_reaches_its_target_by_line_and_by_graph(fitted):
    for path in ("line", "graph"):
        c = controller(fitted, seed=5)
        c.run([Move(take="happy 0", frame=40, path=path)])
        target = c.fields["happy"].X[fitted.sets["happy"].rows("happy 0")[40]]
        assert np.linalg.norm(c.particle.x - target) <= 1.02 * c.settings.particle.radius
        assert c.log[-1].success


def test_a_particle_resting_on_the_wall_has_arrived(fitted):
    # the random force drifts a stopped particle onto the wall, where Baumgarte's term
    # leaves it ~1e-5 r outside; a strict ``≤ r`` timed MOVEs out there
    c = controller(fitted, seed=0)
    c.run([Move(take="happy 0", frame=40)])
    target = c.fields["happy"].X[fitted.sets["happy"].rows("happy 0")[40]]
    r = c.settings.particle.radius
    u = np.array([0.6, 0.0, 0.8])
    c.particle.place(target + r * (1.0 + 1e-5) * u)
    assert c._settled(target, r)
    c.particle.place(target + 1.01 * r * u)
    assert not c._settled(target, r)  # a hundredth of r out is not there yet
    c.particle.place(target + 0.5 * r * u, v=np.array([1.0, 0.0, 0.0]))
    assert not c._settled(target, r)  # inside but too fast for the wall to stop it


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4, 5])
def test_every_move_of_a_seeded_suite_arrives(fitted, seed):
    from rigmap.latent.measures import suite_commands

    c = controller(fitted, seed=seed)
    c.run(suite_commands(fitted, "move", 6, seed, "happy"))
    moves = [e for e in c.log if isinstance(e.command, Move)]
    assert len(moves) == 6
    assert all(e.success for e in moves), [(e.frames, e.command) for e in moves]


def test_graph_path_follows_the_training_points(fitted):
    c = controller(fitted)
    X = c.fields["happy"].X
    start, target = X[0], X[-1]
    line = c.path_points(start, target, "line")
    graph = c.path_points(start, target, "graph")
    np.testing.assert_allclose(graph[-1], target, atol=1e-12)
    nearest = lambda P: np.sqrt(((P[:, None] - X[None]) ** 2).sum(-1)).min(1).mean()  # noqa: E731
    assert nearest(graph) < nearest(line)
    steps = np.linalg.norm(np.diff(graph, axis=0), axis=1)
    assert steps.max() <= c.settings.speed / 24 * 1.0001  # constant speed, resampled


def test_play_reproduces_the_training_take(fitted):
    c = controller(fitted, seed=2, start="roar")
    out = c.run([Play("roar 1")])
    take = fitted.sets["roar"].take("roar 1")
    played = out[-len(take) - 1 : -1]  # the run's last frame is the idle after it
    model = fitted.models["roar"]
    rows = fitted.sets["roar"].rows("roar 1")
    np.testing.assert_allclose(played, model.to_controls(model.latent[rows]), atol=1e-9)
    rig = face_rig()
    a, b = rig.mesh(rig.expand_used(take)), rig.mesh(rig.expand_used(played))
    error = np.sqrt(((a - b) ** 2).sum(-1).mean())
    spread = np.sqrt(((a - a.mean(0)) ** 2).sum(-1).mean())
    assert error < 0.02 * spread  # on the mesh, where the scaling makes it count (§4.2)
    assert c.log[-1].success


def test_transition_switches_models_with_a_blend(fitted):
    c = controller(fitted, seed=4)
    out = c.run([Move(take="happy 1", frame=25), Transition("roar", idle_frames=12)])
    entry = c.log[-1]
    assert c.model == "roar" and entry.success and len(entry.switches) == 1
    start = entry.switches[0]
    blend = out[start : start + c.settings.blend_frames]
    assert len(blend) == c.settings.blend_frames
    jumps = np.abs(np.diff(out[start - 3 : start + 15], axis=0)).max()
    assert jumps < 0.2  # no pop at the crossing (sliders span 0..1)


def test_commands_naming_unknown_models_or_segments_are_errors(fitted):
    c = controller(fitted)
    with pytest.raises(LatentInputError, match="unknown model 'sleepy'"):
        c.submit(Transition("sleepy"))
    with pytest.raises(LatentInputError, match="unknown segment 'roar 0' in model 'happy'"):
        c.submit(Play("roar 0"))
    with pytest.raises(LatentInputError, match="unknown segment 'happy 9'"):
        c.submit(Move(take="happy 9"))
    with pytest.raises(LatentInputError, match="frame 999"):
        c.submit(Idle(10, take="happy 0", frame=999))
    with pytest.raises(LatentInputError, match="unknown model"):
        Controller(fitted.models, start="sleepy")
    c.submit(Transition("roar"))
    c.submit(Play("roar 0"))  # after the transition, roar's segments are the ones named
    with pytest.raises(LatentInputError, match="in model 'roar'"):
        c.submit(Play("happy 0"))


def test_a_yaml_script_runs_like_its_commands(fitted, tmp_path):
    from rigmap.latent.scripts import read_script

    path = tmp_path / "shot.yaml"
    path.write_text(
        "start: happy\n"
        "commands:\n"
        "  - move: {take: happy 1, frame: 20}\n"
        "  - idle: {frames: 12}\n"
        "  - transition: {model: neutral}\n"
        "  - play: {take: neutral 0}\n"
    )
    start, commands = read_script(path)
    assert start == "happy"
    assert commands == [
        Move(take="happy 1", frame=20),
        Idle(12),
        Transition("neutral"),
        Play("neutral 0"),
    ]
    a = controller(fitted, seed=3, start=start).run(commands)
    b = controller(fitted, seed=3).run(
        [Move(take="happy 1", frame=20), Idle(12), Transition("neutral"), Play("neutral 0")]
    )
    np.testing.assert_array_equal(a, b)


def test_bad_scripts_are_errors_naming_the_command(tmp_path):
    from rigmap.latent.scripts import parse_script, read_script

    with pytest.raises(LatentInputError, match="command 2: unknown command 'dance'"):
        parse_script({"commands": [{"idle": {"frames": 3}}, {"dance": {}}]})
    with pytest.raises(LatentInputError, match=r"command 1: idle takes .*'speed'"):
        parse_script({"commands": [{"idle": {"frames": 3, "speed": 2}}]})
    with pytest.raises(LatentInputError, match="'commands'"):
        parse_script({"start": "happy"})
    bad = tmp_path / "bad.yaml"
    bad.write_text("commands: [\n")
    with pytest.raises(LatentInputError, match=r"bad\.yaml"):
        read_script(bad)


def test_the_shipped_example_script_parses():
    from pathlib import Path

    from rigmap.latent.scripts import read_script

    path = Path(__file__).resolve().parents[1] / "conf/latent/scripts/roar_after_idle.yaml"
    start, commands = read_script(path)
    assert start == "happy"
    assert [type(c).__name__ for c in commands] == [
        "Move",
        "Idle",
        "Transition",
        "Idle",
        "Transition",
        "Play",
        "Idle",
    ]


def test_a_script_past_the_frame_cap_is_refused_naming_the_file_command_and_range(tmp_path):
    """Refused while reading: the script, the command that crosses the cap, the range."""
    from rigmap.latent.scripts import MAX_SCRIPT_FRAMES, read_script

    huge = tmp_path / "huge.yaml"
    huge.write_text("commands:\n  - move: {take: happy 1}\n  - idle: {frames: 10000000}\n")
    with pytest.raises(LatentInputError) as refused:
        read_script(huge)
    message = str(refused.value)
    assert message.startswith(f"{huge}: command 2 (idle frames=10000000) passes the cap")
    assert f"accepted: 0 to {MAX_SCRIPT_FRAMES} frames in all" in message
    both = tmp_path / "both.yaml"
    both.write_text(
        "commands:\n  - idle: {frames: 30}\n  - idle: {frames: 20}\n"
        "  - transition: {model: roar, idle_frames: 1}\n"
    )
    assert len(read_script(both, max_frames=51)[1]) == 3  # 51 frames: exactly at the cap
    with pytest.raises(LatentInputError, match=r"command 3 \(transition idle_frames=1\)"):
        read_script(both, max_frames=50)


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (0, "expected a whole number >= 1"),
        (2.5, "expected a whole number >= 1"),
        (10**9, "expected at most 1000000"),
    ],
)
def test_the_frame_cap_itself_is_bounded(value, message):
    from rigmap.latent.steps import max_script_frames

    with pytest.raises(LatentInputError, match=rf"latent\.max_script_frames={value}: {message}"):
        max_script_frames({"max_script_frames": value})
    assert max_script_frames({}) == 100_000


def test_a_run_past_the_cap_names_the_command_playing(fitted, capsys):
    """A take's length is not known to the script: the controller stops it at the cap."""
    take = fitted.sets["happy"].names[0]
    with pytest.raises(LatentInputError, match=rf"stopped at frame 5 in Play\(take='{take}'\)"):
        controller(fitted).run([Idle(2), Play(take)], max_frames=5, progress=True)
    assert "synthesis" in capsys.readouterr().err  # the progress bar, on stderr
