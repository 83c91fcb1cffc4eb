"""Configuration: params.yaml is fresh, overrides compose, bad keys fail naming the key."""

from __future__ import annotations

import re
import shutil
import subprocess

import pytest
import yaml

from locoman.config import validate
from locoman.config.compose import compose_text
from locoman.errors import ConfigError
from locoman.stage import StageOutputs


@pytest.fixture(scope="module")
def raw(repo):
    return yaml.safe_load((repo / "params.yaml").read_text())


def _git(repo, *args) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["git", *args], cwd=repo, capture_output=True, text=True)


def _expected_params(repo) -> tuple[str, str]:
    """What params.yaml must equal (conf/ composed) and which file that is. `dvc exp run -S
    key=value` rewrites params.yaml in the workspace with its overrides, a legitimate
    workflow: while conf/ is as committed, the committed params.yaml is the one compared."""
    conf_as_committed = _git(repo, "diff", "--quiet", "HEAD", "--", "conf").returncode == 0
    committed = _git(repo, "show", "HEAD:params.yaml")
    if conf_as_committed and committed.returncode == 0:
        return committed.stdout, "the committed params.yaml"
    # conf/ edited (or no git): the workspace's params.yaml must follow it
    return (repo / "params.yaml").read_text(), "params.yaml"


# DVC's run cache drops every key named like a file's metadata from a stage's hash, at any depth
# (treeverse/dvc#10296, open in the pinned DVC): changing such a parameter restores the previous
# run's outputs. Drop this guard when a DVC with the fix (treeverse/dvc#11079) is pinned.
DVC_DROPPED_KEYS = {"size", "nfiles"}


def _keys_dvc_drops(node, path=()):
    if isinstance(node, dict):
        for key, value in node.items():
            if key in DVC_DROPPED_KEYS:
                yield ".".join(map(str, (*path, key)))
            yield from _keys_dvc_drops(value, (*path, key))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from _keys_dvc_drops(value, (*path, i))


def test_no_parameter_key_is_one_dvcs_run_cache_drops(raw):
    dropped = list(_keys_dvc_drops(raw))
    assert not dropped, (
        f"params.yaml keys {dropped}: DVC's run cache leaves keys named {sorted(DVC_DROPPED_KEYS)} "
        "out of the stage hash (treeverse/dvc#10296), so changing them restores stale outputs; "
        "rename them (objects use extents_m)"
    )


def test_the_guard_finds_a_nested_size_key():
    found = list(_keys_dvc_drops({"a": [{"b": {"size": 1}}], "nfiles": 2}))
    assert found == ["a.0.b.size", "nfiles"]


def test_committed_params_is_not_stale(repo, monkeypatch):
    monkeypatch.chdir(repo)
    expected, where = _expected_params(repo)
    assert compose_text([]) == expected, f"{where} is stale against conf/; run `make params`"


def test_an_experiments_overrides_in_params_do_not_count_as_stale(repo, tmp_path, monkeypatch):
    """In a copy of the project after `dvc exp run -S scenario.box_mass=2.5`, which leaves
    the override in params.yaml; and after an edit of conf/ without `make params`."""
    copy = tmp_path / "project"
    shutil.copytree(repo / "conf", copy / "conf")
    (copy / "params.yaml").write_text((repo / "params.yaml").read_text())
    identity = ["-c", "user.name=t", "-c", "user.email=t@example.com"]
    for args in (["init", "-q"], ["add", "-A"], [*identity, "commit", "-qm", "base"]):
        assert _git(copy, *args).returncode == 0
    params = copy / "params.yaml"
    params.write_text(params.read_text().replace("box_mass: 5.0", "box_mass: 2.5", 1))
    monkeypatch.chdir(copy)
    assert compose_text([]) == _expected_params(copy)[0]
    config = copy / "conf" / "config.yaml"
    config.write_text(config.read_text().replace("box_mass: 5.0", "box_mass: 7.5", 1))
    assert compose_text([]) != _expected_params(copy)[0]


def test_box_mass_override_reaches_every_humanoid_scenario(repo, monkeypatch):
    monkeypatch.chdir(repo)
    cfg = validate(yaml.safe_load(compose_text(["scenario.box_mass=2.5"])))
    for name in ("tiny", "s1_basket", "s2_trolley"):
        assert cfg.scenarios[name].objects["box"].mass == 2.5
    assert cfg.scenarios["mm_pick_place"].objects["bottle"].mass == 0.3


def test_unknown_override_key_fails(repo, monkeypatch):
    monkeypatch.chdir(repo)
    with pytest.raises(Exception, match="box_mas"):
        compose_text(["scenario.box_mas=2.5"])


def test_unknown_key_is_named(raw):
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["scenarios"]["tiny"]["objects"]["box"]["colour"] = "red"
    with pytest.raises(ConfigError, match=r"scenarios\.tiny\.objects\.box\.colour"):
        validate(bad)


def test_wrong_type_is_named(raw):
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["scenario"]["box_mass"] = "heavy"
    with pytest.raises(ConfigError, match=r"scenario\.box_mass"):
        validate(bad)


def test_out_of_range_value_is_named(raw):
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["scenarios"]["s1_basket"]["objects"]["box"]["mass"] = -1.0
    with pytest.raises(ConfigError, match=r"scenarios\.s1_basket\.objects\.box\.mass"):
        validate(bad)


def test_plan_must_name_known_objects(raw):
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["scenarios"]["tiny"]["plan"][1]["object"] = "crate"
    with pytest.raises(ConfigError, match=r"scenarios\.tiny\.plan\[1\]\.object"):
        validate(bad)


@pytest.mark.parametrize("value", [float("nan"), -1.0, 0.0, float("inf")])
def test_a_via_point_variance_must_be_finite_and_positive(raw, value):
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["kmp"]["cases"]["replica"]["via_points"][0]["wrist_vel_variance"] = value
    with pytest.raises(ConfigError, match=r"wrist_vel_variance"):
        validate(bad)


def test_a_large_via_point_variance_is_accepted(raw):
    ok = yaml.safe_load(yaml.safe_dump(raw))
    ok["kmp"]["cases"]["replica"]["via_points"][0]["wrist_vel_variance"] = 10.0
    ok["kmp"]["via_point_variance"] = 1.0
    assert validate(ok).kmp.cases["replica"].via_points[0].wrist_vel_variance == 10.0


@pytest.mark.parametrize("name", ["../../traversal_x", "a/b", "", ".hidden", "x" * 65])
def test_a_scenario_name_that_is_a_path_is_refused(raw, name, tmp_path, monkeypatch):
    """issue 24: the key ``../../traversal_x`` wrote 6 files outside the repository."""
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["scenarios"][name] = bad["scenarios"]["tiny"]
    with pytest.raises(ConfigError, match="scenario name is a folder"):
        validate(bad)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError, match="scenario name is a folder"):
        StageOutputs().folder(name, "scene")
    assert list(tmp_path.rglob("*")) == []


NON_FINITE_KEYS = [
    ("scenario", "initial_yaw"),
    ("scenarios", "tiny", "start", "yaw"),
    ("scenarios", "tiny", "start", "xy", 0),
    ("scenarios", "tiny", "objects", "box", "pos", 1),
    ("scenarios", "tiny", "objects", "box", "extents_m", 2),
    ("solve", "contact", "floor_friction"),
    ("solve", "solver", "tolerance"),
    ("evaluate", "goal_tol_m"),
    ("retarget", "com_margin_m"),
    ("hqp", "kp"),
]


@pytest.mark.parametrize("value", [float("nan"), float("inf"), float("-inf")])
@pytest.mark.parametrize("path", NON_FINITE_KEYS, ids=lambda p: ".".join(map(str, p)))
def test_a_number_that_is_not_finite_is_refused_naming_its_key(raw, path, value):
    bad = yaml.safe_load(yaml.safe_dump(raw))
    node = bad
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    name = ".".join(f"[{k}]" if isinstance(k, int) else k for k in path).replace(".[", "[")
    with pytest.raises(ConfigError, match=re.escape(name)):
        validate(bad)


def test_nan_leaves_a_via_point_output_free(raw):
    ok = yaml.safe_load(yaml.safe_dump(raw))
    ok["kmp"]["cases"]["replica"]["via_points"][0]["wrist_vel"] = [float("nan"), 0.1, 0.0]
    validate(ok)
    ok["kmp"]["cases"]["replica"]["via_points"][0]["wrist_vel"][0] = float("inf")
    with pytest.raises(ConfigError, match=r"via_points\[0\]\.wrist_vel\[0\]"):
        validate(ok)


def test_a_renamed_key_is_a_message_not_a_traceback(repo, tmp_path):
    """conf/ with scenario.box_mass renamed: the scenarios' ${scenario.box_mass} dangles."""
    shutil.copytree(repo / "conf", tmp_path / "conf")
    config = tmp_path / "conf" / "config.yaml"
    config.write_text(config.read_text().replace("box_mass:", "mass_of_box:"))
    with pytest.raises(ConfigError, match=r"box_mass"):
        compose_text([], conf_dir=tmp_path / "conf")


def test_a_misspelt_override_is_a_message(repo, monkeypatch):
    monkeypatch.chdir(repo)
    with pytest.raises(ConfigError, match=r"box_mas"):
        compose_text(["scenario.box_mas=2.5"])


@pytest.mark.parametrize(
    ("path", "value"),
    [
        (("kmp", "n_reference"), 100_000),
        (("kmp", "gmm_components"), 1000),
        (("demos", "n_recorded"), 100_000),
        (("contacts", "pool", "points"), 1_000_000),
        (("contacts", "registration", "model_points"), 10_000_000),
        (("retarget", "iterations"), 10**9),
        (("solve", "solver", "max_iterations"), 10**9),
    ],
    ids=lambda p: ".".join(p) if isinstance(p, tuple) else str(p),
)
def test_a_size_beyond_what_it_costs_is_refused_with_its_bound(raw, path, value):
    """issue 53: ``swing_nodes: 100000`` ran two minutes into std::bad_alloc; every size is
    checked with the configuration, the message giving the value, the bound and why."""
    bad = yaml.safe_load(yaml.safe_dump(raw))
    node = bad
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    with pytest.raises(ConfigError, match=re.escape(".".join(path)) + r".*above its bound"):
        validate(bad)


def test_a_negative_unfreed_depth_is_refused(raw):
    """issue 48: the depth beyond which a pair the rounds leave fails the solve [m]."""
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["solve"]["collision"]["unfreed_m"] = -0.01
    with pytest.raises(ConfigError, match=r"solve\.collision\.unfreed_m: must be >= 0 m"):
        validate(bad)


@pytest.mark.parametrize("value", [0.0, -0.01])
def test_a_slack_bound_that_is_not_positive_is_refused(raw, value):
    """issue 48: |s| <= contact.slack_max_m [m]; 0 would leave no slack, null none."""
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["solve"]["contact"]["slack_max_m"] = value
    with pytest.raises(ConfigError, match=r"solve\.contact\.slack_max_m: must be > 0 m"):
        validate(bad)
    bad["solve"]["contact"]["slack_max_m"] = None
    validate(bad)


def test_a_sole_cone_other_than_paper_or_exact_is_refused(raw):
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["solve"]["contact"]["sole_cone"] = "exactly"
    with pytest.raises(
        ConfigError, match=r"solve\.contact\.sole_cone: must be one of paper, exact"
    ):
        validate(bad)
    bad["solve"]["contact"]["sole_cone"] = "exact"
    validate(bad)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("settled_change", 0.0, r"settled_change: must be in \(0, 1\)"),
        ("settled_change", 2.0, r"settled_change: must be in \(0, 1\)"),
        ("settled_iterations", 0, r"settled_iterations: must be >= 1"),
    ],
)
def test_a_settled_stop_out_of_range_is_refused(raw, key, value, message):
    """The exact Hessian's acceptable stop: a relative change in (0, 1), iterations >= 1."""
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["solve"]["solver"][key] = value
    with pytest.raises(ConfigError, match=r"solve\.solver\." + message):
        validate(bad)
    bad["solve"]["solver"] |= {"settled_change": None, "settled_iterations": 10}
    assert validate(bad).solve.solver.settled_change is None


def test_negative_second_order_corrections_are_refused(raw):
    """IPOPT's ``max_soc`` counts corrections: 0 or more."""
    bad = yaml.safe_load(yaml.safe_dump(raw))
    bad["solve"]["solver"]["second_order_corrections"] = -1
    with pytest.raises(ConfigError, match=r"solve\.solver\.second_order_corrections: must be >= 0"):
        validate(bad)
