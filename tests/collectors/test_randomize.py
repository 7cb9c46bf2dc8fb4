"""Domain randomization: profiles, draws, where they land, and bad profiles refused."""

import json
from dataclasses import asdict

import numpy as np
import pytest
from clitools import assert_clean_error, cli

from collectors.randomize import (
    PROFILES,
    Randomization,
    around,
    check_fits,
    randomize_model,
    randomized_noise,
    randomized_scenario,
)
from macrostate_mj.chain.scenarios import get_scenario
from macrostate_mj.chain.world import build_world
from macrostate_mj.core.errors import UserError
from macrostate_mj.vision.imaging import NoiseConfig


def test_draws_are_seeded_within_their_ranges_and_land_where_they_belong():
    for profile, ranges in PROFILES.items():
        r = Randomization.parse(profile)
        draws = [r.draw(np.random.default_rng(s)) for s in range(200)]
        for name, bounds in ranges.items():
            values = [d[name] for d in draws]
            if isinstance(bounds, float):                   # a fixed factor (`refit`)
                assert set(values) == {bounds}
                continue
            low, high = bounds
            assert low <= min(values) and max(values) <= high and np.std(values) > 0
        assert r.draw(np.random.default_rng(5)) == r.draw(np.random.default_rng(5))
    f = {"k_f": 1.1, "sensor_sigma": 2.0, "wheel_friction": 0.5, "motor_torque": 1.25,
         "marker_jitter": 1.3, "head_jitter_scale": 0.7}
    cfg = get_scenario("lab")
    assert randomized_scenario(cfg, f).k_f == pytest.approx(1.1 * cfg.k_f)
    assert randomized_scenario(cfg, f).marker_jitter == pytest.approx(1.3 * cfg.marker_jitter)
    assert randomized_scenario(cfg, f).head_jitter_scale == pytest.approx(0.7)
    assert randomized_noise(NoiseConfig(), f).sensor_sigma == pytest.approx(6.0)
    world = build_world(cfg, 3)
    grip = world.model.geom("H/wheel_left").friction[0]
    torque = world.model.actuator_forcerange[world.ctrl_left[0]].copy()
    randomize_model(world, f)
    assert world.model.geom("H/wheel_left").friction[0] == pytest.approx(0.5 * grip)
    assert np.allclose(world.model.actuator_forcerange[world.ctrl_left[0]], 1.25 * torque)


@pytest.mark.parametrize(("ranges", "words"), [
    ({"k_x": [0.8, 1.2]}, "unknown parameter 'k_x'"),
    ({"k_f": [1.2, 1.2]}, "empty"),
    ({"k_f": [0.0, 1.2]}, "positive"),
    ({"k_f": "wide"}, "[low, high]"),
])
def test_bad_profiles_are_refused(tmp_path, ranges, words):
    path = tmp_path / "p.json"
    path.write_text(json.dumps(ranges))
    with pytest.raises(UserError, match=words.replace("[", r"\[").replace("]", r"\]")):
        Randomization.parse(str(path))


def test_collect_randomize_records_its_draws_and_refuses_bad_input(tmp_path):
    args = ["collect", "--robots", "3", "--minutes", "0.5", "--episode-minutes", "0.25",
            "--seed", "4", "--randomize", "wide"]
    res = cli(*args, "--out", str(tmp_path / "a"))
    assert res.returncode == 0, res.stderr
    manifest = json.loads((tmp_path / "a" / "manifest.json").read_text())
    assert manifest["randomization"]["name"] == "wide"
    drawn = [s["randomized"] for s in manifest["episode_stats"].values()]
    assert len(drawn) == 2 and drawn[0] != drawn[1] and set(drawn[0]) == set(PROFILES["wide"])
    bad = tmp_path / "bad.json"
    bad.write_text('{"gravity": [0.9, 1.1]}')
    res = cli(*args[:-1], str(bad), "--out", str(tmp_path / "b"))
    assert_clean_error(res, "unknown parameter 'gravity'")
    assert not (tmp_path / "b").exists()


def test_a_bare_number_fixes_a_factor(tmp_path):
    from collectors.randomize import randomized_scenario
    from macrostate_mj.chain.scenarios import get_scenario

    path = tmp_path / "fixed.json"
    path.write_text(json.dumps({"k_f": 1.25, "wait_slack": 2.0}))
    r = Randomization.parse(str(path))
    rng = np.random.default_rng(0)
    assert r.draw(rng) == r.draw(rng) == {"k_f": 1.25, "wait_slack": 2.0}
    lab = get_scenario("lab")
    fitted = randomized_scenario(lab, r.draw(rng))
    assert fitted.k_f == lab.k_f * 1.25 and fitted.followers.slack == lab.followers.slack * 2
    path.write_text(json.dumps({"k_f": 0}))
    with pytest.raises(UserError, match="positive"):
        Randomization.parse(str(path))


def test_absolute_parameters_add_to_the_scenario_and_their_extremes_are_checked(tmp_path):
    """The frame timing jitter and the rear robots' start gap are zero in the built-in labs:
    a profile adds to them in their own unit (0 is a valid low), `around` shifts their range
    by the fitted value, and a profile whose highest frame rate leaves no room for its jitter
    is refused before any episode."""
    lab = get_scenario("lab")
    cfg = randomized_scenario(lab, {"frame_hz": 0.75, "frame_jitter": 0.05,
                                    "follow_start": 0.02, "wait_slack": 2.0})
    assert cfg.camera_hz == 3.0 and cfg.frame_jitter == 0.05
    assert cfg.followers.start == 0.02 and cfg.followers.slack == 2 * lab.followers.slack
    assert lab.frame_hz is None and lab.camera_hz == lab.command_hz == 4.0
    profile = tmp_path / "p.json"
    profile.write_text(json.dumps({"frame_jitter": [0.0, 0.1], "frame_hz": [0.8, 1.2]}))
    parsed = Randomization.parse(str(profile))
    assert parsed.profile() == {"frame_hz": (0.8, 1.2), "frame_jitter": (0.0, 0.1)}
    check_fits(parsed, lab)
    assert around({"frame_jitter": 0.05, "k_f": 2.0}, {"frame_jitter": (0.0, 0.1),
                                                        "k_f": (0.5, 1.5)}) == \
        {"frame_jitter": (0.05, pytest.approx(0.15)), "k_f": (1.0, 3.0)}
    profile.write_text(json.dumps({"frame_jitter": [0.0, 0.2], "frame_hz": [1.0, 1.6]}))
    with pytest.raises(UserError, match="highest values.*frame_jitter"):
        check_fits(Randomization.parse(str(profile)), lab)
    profile.write_text(json.dumps({"k_f": [0.0, 1.2]}))
    with pytest.raises(UserError, match="positive factors with 0 < low"):
        Randomization.parse(str(profile))


def test_the_heads_driving_is_drawn_where_it_lives():
    """`head_turn_speed` adds to the scenario's share (0 as written); `max_turn` scales a Psi
    Head's largest turn, capped at 180 degrees; a lab whose Head is not Psi's refuses it."""
    lab = get_scenario("lab")
    assert lab.head_turn_speed == 0.0 and lab.planner.max_turn == 180.0
    cfg = randomized_scenario(lab, {"head_turn_speed": 0.7, "max_turn": 0.5})
    assert cfg.head_turn_speed == 0.7 and cfg.planner.max_turn == 90.0
    assert cfg.planner.grid == lab.planner.grid
    assert randomized_scenario(lab, {"max_turn": 1.3}).planner.max_turn == 180.0
    with pytest.raises(UserError, match="max_turn turns a Psi Head"):
        randomized_scenario(get_scenario("webots"), {"max_turn": 0.5})
    with pytest.raises(UserError, match="head_turn_speed .* must be a share in"):
        randomized_scenario(lab, {"head_turn_speed": 1.5})


@pytest.mark.parametrize(("key", "value"), [("frame_jitter", 0.3), ("frame_hz", -1.0),
                                            ("wheel_spread", float("nan")),
                                            ("marker_offset", 0.5),
                                            ("head_turn_speed", float("nan")),
                                            ("head_turn_speed", -0.1)])
def test_the_new_keys_refuse_bad_values_from_python_in_one_line(key, value):
    with pytest.raises(ValueError, match=f"{key} \\(.* in a scenario file\\) must be"):
        get_scenario("lab").with_overrides(**{key: value})


def test_episodes_with_wheels_that_differ_are_keyed_apart_from_those_made_before():
    """An episode whose wheels may differ (the scenario's `wheel_spread` or a profile that
    draws it) has a key of its own since the spread turns the commanded rate instead of the
    wheels' shape; every other episode keeps its key (its cached data stays valid)."""
    from collectors.episodes import EpisodeSpec
    from collectors.runner import EpisodeTask
    from macrostate_mj.core.cache import task_key

    def key(spec):
        fields = {k: v for k, v in asdict(spec).items() if k != "scenario"}
        made = {"spec": fields, "scenario": spec.scenario.as_made()}
        return task_key(EpisodeTask.stage, EpisodeTask.version, made)

    plain = EpisodeSpec(get_scenario("lab"), 3, 60.0, 5.0, 1, 0)
    assert EpisodeTask(plain).key() == key(plain)
    drawn = EpisodeSpec(get_scenario("lab"), 3, 60.0, 5.0, 1, 0,
                        randomize=Randomization(name="x", ranges=(("wheel_spread", 0.0, 0.02),)))
    assert EpisodeTask(drawn).key() != key(drawn)


def test_a_profile_counts_by_its_ranges_not_by_where_its_file_lies(tmp_path):
    """A collection drawn from a profile file is finished for another copy of that file (a run
    folder moved with its profile beside it: `experiment sim2real` resumes it instead of
    simulating it again), and its episodes keep their keys; other ranges are another
    collection."""
    from collectors.runner import CollectRequest, EpisodeTask, finished, plan

    first, moved = tmp_path / "a.json", tmp_path / "elsewhere" / "a.json"
    moved.parent.mkdir()
    for path in (first, moved):
        path.write_text(json.dumps({"k_f": [0.9, 1.1]}))
    res = cli("collect", "--robots", "3", "--minutes", "0.5", "--episode-minutes", "0.25",
              "--seed", "4", "--out", str(tmp_path / "run"), "--randomize", str(first))
    assert res.returncode == 0, res.stderr

    def request(profile):
        return CollectRequest(get_scenario("lab"), 3, 0.5, 4, tmp_path / "run",
                              episode_minutes=0.25, randomize=str(profile))

    assert finished(request(first)) and finished(request(moved))
    assert [EpisodeTask(s).key() for s in plan(request(first))] == \
        [EpisodeTask(s).key() for s in plan(request(moved))]
    moved.write_text(json.dumps({"k_f": [0.9, 1.2]}))
    assert not finished(request(moved))
