"""blindspot.config: Hydra composition, params.yaml round trip and the params check."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from blindspot import cli, config
from tests.pipeline.toy_repo import REPO, make_toy_repo


@pytest.fixture()
def toy(tmp_path: Path) -> Path:
    return make_toy_repo(tmp_path / "repo")


def test_compose_reads_groups_and_overrides(toy: Path) -> None:
    cfg = config.compose(config_dir=toy / "conf")
    assert cfg.model.hidden_size == 16 and cfg.train.lr == 0.1 and cfg.seed == 0
    assert "hydra" not in cfg
    cfg = config.compose(["train.lr=0.01", "model.hidden_size=64"], config_dir=toy / "conf")
    assert cfg.train.lr == 0.01 and cfg.model.hidden_size == 64


def test_compose_rejects_unknown_key(toy: Path) -> None:
    from hydra.errors import ConfigCompositionException

    with pytest.raises(ConfigCompositionException, match="trian"):
        config.compose(["trian.lr=1"], config_dir=toy / "conf")


def test_params_yaml_round_trip_and_identical_to_dvc_dump(toy: Path, tmp_path: Path) -> None:
    path = config.write_params(toy)
    assert path == toy / "params.yaml"
    loaded = config.load_params(toy)
    assert OmegaConf.to_container(loaded) == OmegaConf.to_container(
        config.compose(config_dir=toy / "conf")
    )
    config.check_params(toy)  # fresh file: no error
    # DVC's own composition (what `dvc exp run` writes with hydra.enabled) gives the same bytes,
    # so `dvc exp run` without overrides never rewrites params.yaml.
    from dvc.utils.hydra import compose_and_dump

    dvc_out = tmp_path / "dvc_params.yaml"
    compose_and_dump(dvc_out, str(toy / "conf"), None, "config", str(toy), [])
    assert dvc_out.read_bytes() == path.read_bytes()
    # Rewriting an up-to-date file keeps it byte-identical (and leaves no temp files).
    before = path.stat().st_mtime_ns
    config.write_params(toy)
    assert path.stat().st_mtime_ns == before
    assert sorted(p.name for p in toy.iterdir() if ".tmp-" in p.name) == []


def test_check_params_detects_edited_conf_value(toy: Path) -> None:
    config.write_params(toy)
    (toy / "conf" / "train" / "base.yaml").write_text("lr: 0.2\nepochs: 2\nmomentum: 0.9\n")
    with pytest.raises(config.ParamsOutOfDate) as err:
        config.check_params(toy)
    diff = {d.key: d for d in err.value.differences}
    assert set(diff) == {"train.lr", "train.momentum"}
    assert diff["train.lr"].in_params == 0.1 and diff["train.lr"].in_conf == 0.2
    message = str(err.value)
    assert "python -m blindspot params" in message
    assert "train.lr: params.yaml has 0.1, conf/ gives 0.2" in message
    assert "train.momentum: params.yaml has <absent>" in message
    config.write_params(toy)
    config.check_params(toy)


def test_check_params_detects_hand_edited_params(toy: Path) -> None:
    config.write_params(toy)
    text = (toy / "params.yaml").read_text().replace("hidden_size: 16", "hidden_size: 17")
    (toy / "params.yaml").write_text(text)
    with pytest.raises(config.ParamsOutOfDate, match="model.hidden_size"):
        config.check_params(toy)


def _counting_compose(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls: list[int] = []
    real = config.compose

    def compose(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(config, "compose", compose)
    return calls


def test_check_params_stamp_skips_compose_only_while_nothing_changed(
        toy: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Every DVC stage checks params.yaml (blindspot.cli.main_stage); the stamp of a passing
    check spares the Hydra compose, and any edit of conf/ or params.yaml (by hand) brings the
    full comparison back."""
    (toy / ".dvc").mkdir()
    config.write_params(toy)
    composed = _counting_compose(monkeypatch)
    stamp = toy / cli.STAMP_FILE
    cli.check_params_stamped(toy)
    assert len(composed) == 1 and stamp.read_text().strip() == cli.params_fingerprint(toy)
    cli.check_params_stamped(toy)
    assert len(composed) == 1  # stamped: no composition
    cli.check_params_stamped(toy, stamp=False)  # `python -m blindspot check-params`: always composes
    assert len(composed) == 2
    # conf/ edited by hand: the stamp no longer matches, the full check fails and names the key
    (toy / "conf" / "train" / "base.yaml").write_text("lr: 0.2\nepochs: 2\n")
    with pytest.raises(config.ParamsOutOfDate, match="train.lr: params.yaml has 0.1, conf/ gives 0.2"):
        cli.check_params_stamped(toy)
    assert not stamp.exists()
    with pytest.raises(config.ParamsOutOfDate):  # and again: a failure is never stamped
        cli.check_params_stamped(toy)
    config.write_params(toy)
    cli.check_params_stamped(toy)
    assert stamp.is_file()
    # params.yaml edited by hand: a changed value fails, a comment only passes (values compared)
    text = (toy / "params.yaml").read_text()
    (toy / "params.yaml").write_text(text.replace("hidden_size: 16", "hidden_size: 17"))
    with pytest.raises(config.ParamsOutOfDate, match="model.hidden_size"):
        cli.check_params_stamped(toy)
    (toy / "params.yaml").write_text(text + "# a comment\n")
    before = len(composed)
    cli.check_params_stamped(toy)
    cli.check_params_stamped(toy)
    assert len(composed) == before + 1


def test_check_params_stamp_covers_environment_variables_conf_reads(
        toy: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (toy / ".dvc").mkdir()
    conf = toy / "conf" / "config.yaml"
    conf.write_text(conf.read_text() + "workers: ${oc.env:BLINDSPOT_TEST_WORKERS,1}\n")
    monkeypatch.setenv("BLINDSPOT_TEST_WORKERS", "3")
    config.write_params(toy)
    cli.check_params_stamped(toy)
    monkeypatch.setenv("BLINDSPOT_TEST_WORKERS", "4")
    with pytest.raises(config.ParamsOutOfDate, match="workers: params.yaml has '3', conf/ gives '4'"):
        cli.check_params_stamped(toy)


@pytest.mark.parametrize("spelling", ["${oc.env:BLINDSPOT_TEST_WORKERS,1}",
                                      "${oc.env: BLINDSPOT_TEST_WORKERS, 1}",
                                      "${oc.env:'BLINDSPOT_TEST_WORKERS',1}",
                                      "${oc.env:${oc.env:BLINDSPOT_TEST_NAME,X},1}"])
def test_params_fingerprint_follows_every_oc_env_spelling(
        toy: Path, spelling: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """OmegaConf accepts blanks and quoted names in ``${oc.env:...}``; a name read through a
    nested interpolation cannot be read from the file, so the whole environment counts."""
    conf = toy / "conf" / "config.yaml"
    conf.write_text(conf.read_text() + f'workers: "{spelling}"\n')
    config.write_params(toy)
    monkeypatch.setenv("BLINDSPOT_TEST_WORKERS", "3")
    before = cli.params_fingerprint(toy)
    monkeypatch.setenv("BLINDSPOT_TEST_WORKERS", "4")
    assert cli.params_fingerprint(toy) != before


def test_params_fingerprint_walks_symlinked_conf_folders(toy: Path, tmp_path: Path) -> None:
    outside = tmp_path / "shared_group"
    outside.mkdir()
    (outside / "big.yaml").write_text("hidden_size: 64\n")
    (toy / "conf" / "extra").symlink_to(outside, target_is_directory=True)
    config.write_params(toy)
    before = cli.params_fingerprint(toy)
    (outside / "big.yaml").write_text("hidden_size: 65\n")
    assert cli.params_fingerprint(toy) != before
    # a broken link (an editor's lock file) and a link back to a parent folder: no error, no loop
    (toy / "conf" / ".#config.yaml").symlink_to(toy / "nowhere@host.1234")
    (outside / "up").symlink_to(toy / "conf", target_is_directory=True)
    assert cli.params_fingerprint(toy) == cli.params_fingerprint(toy)


def test_params_fingerprint_includes_the_installed_omegaconf_version(
        toy: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import importlib.metadata

    config.write_params(toy)
    before = cli.params_fingerprint(toy)
    real = importlib.metadata.version
    monkeypatch.setattr(importlib.metadata, "version",
                        lambda d: "9.9.9" if d == "omegaconf" else real(d))
    assert cli.params_fingerprint(toy) != before


def test_params_fingerprint_changes_with_every_input(toy: Path) -> None:
    config.write_params(toy)
    seen = {cli.params_fingerprint(toy)}
    edits = [
        (toy / "params.yaml", lambda t: t + "\n"),
        (toy / "conf" / "model" / "small.yaml", lambda t: t.replace("16", "16.0")),
        (toy / "conf" / "config.yaml", lambda t: t + "# note\n"),
    ]
    for path, change in edits:
        path.write_text(change(path.read_text()))
        seen.add(cli.params_fingerprint(toy))
    (toy / "conf" / "model" / "small.yaml").rename(toy / "conf" / "model" / "tiny.yaml")
    seen.add(cli.params_fingerprint(toy))  # a renamed file is another config group option
    assert len(seen) == 5


def test_missing_params_yaml_names_the_fix(toy: Path) -> None:
    with pytest.raises(FileNotFoundError, match="python -m blindspot params"):
        config.load_params(toy)
    with pytest.raises(config.ParamsOutOfDate):
        config.check_params(toy)


def test_params_diff_keeps_bool_and_int_apart() -> None:
    assert config.params_diff({"a": True}, {"a": 1})[0].key == "a"
    assert config.params_diff({"a": {"b": 1.0}}, {"a": {"b": 1}}) == []
    assert config.flatten({"a": {"b": {"c": 1}, "d": [1, 2]}, "e": {}}) == {
        "a.b.c": 1, "a.d": [1, 2], "e": {}}


def test_find_repo_root_from_subdirectory(toy: Path, tmp_path: Path) -> None:
    (toy / "stages" / "deep").mkdir()
    assert config.find_repo_root(toy / "stages" / "deep") == toy.resolve()
    assert config.find_repo_root(toy / "stages" / "toy.py") == toy.resolve()
    with pytest.raises(config.ConfigNotFound, match="conf/config.yaml"):
        config.find_repo_root(tmp_path)


def test_original_repo_root_maps_dvc_queue_copies(toy: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("DVC_ROOT", raising=False)
    copy = toy / ".dvc" / "tmp" / "exps" / "tmpab12cd34"
    copy.mkdir(parents=True)
    assert config.original_repo_root(copy) == toy.resolve()
    assert config.original_repo_root(copy / "stages") == toy.resolve()
    assert config.original_repo_root(toy) == toy.resolve()
    # DVC exports DVC_ROOT=<original repo> to queued stages; it wins when it is a repo.
    other = make_toy_repo(toy.parent / "other")
    monkeypatch.setenv("DVC_ROOT", str(other))
    assert config.original_repo_root(copy) == other.resolve()


def test_shared_dir_resolves_from_original_root(toy: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("BLINDSPOT_SHARED", raising=False)
    monkeypatch.delenv("DVC_ROOT", raising=False)
    copy = toy / ".dvc" / "tmp" / "exps" / "tmpzz"
    make_toy_repo(copy)
    monkeypatch.chdir(copy)
    cfg = {"paths": {"shared_dir": "../shared"}}
    assert config.shared_dir(cfg) == (toy.parent / "shared").resolve()
    monkeypatch.setenv("BLINDSPOT_SHARED", str(toy / "elsewhere"))
    assert config.shared_dir(cfg) == (toy / "elsewhere").resolve()


def _real_groups_present() -> bool:
    defaults = OmegaConf.load(REPO / "conf" / "config.yaml").defaults
    for entry in defaults:
        if entry == "_self_":
            continue
        ((group, option),) = entry.items()
        group = group.split("@")[0]           # radar@driving_radar: a radar option elsewhere
        if not (REPO / "conf" / group / f"{option}.yaml").is_file():
            return False
    return True


def test_real_conf_composes_without_hydra_interpolations() -> None:
    if not _real_groups_present():
        pytest.skip("conf/ groups named in conf/config.yaml are not all written yet")
    cfg = config.compose(config_dir=REPO / "conf")
    assert cfg.seed == 0 and cfg.runs.experiment == "blindspot"
    for path in (REPO / "conf").rglob("*.yaml"):
        if "hydra" not in path.relative_to(REPO / "conf").parts:
            assert "${hydra:" not in path.read_text(), f"{path} uses ${{hydra:...}}"


def test_committed_params_yaml_is_up_to_date() -> None:
    if not (REPO / "params.yaml").is_file() or not _real_groups_present():
        pytest.skip("params.yaml or conf/ groups not written yet")
    config.check_params(REPO)


# ----------------------------------------------------------------------------- typed config
def _build_recordings(cfg):
    from blindspot.dsp.config import CfarConfig, DetectConfig, DoaConfig
    from blindspot.radar.config import RadarConfig

    from blindspot.safety.recording import RAW_KINDS, RecordingEntry

    out = {}
    for name, rec in cfg.recordings.items():
        out[name] = [RecordingEntry.from_mapping({**rec, "name": name}, where=f"recordings.{name}")]
        if rec.kind not in RAW_KINDS:      # a point-cloud log: no radar profile, no chain
            continue
        out[name] += [RadarConfig.from_mapping(rec.radar, where=f"recordings.{name}.radar")] + [
            kind.from_mapping(OmegaConf.merge(cfg[g], rec.get(g) or {}), where=f"recordings.{name}.{g}")
            for g, kind in (("cfar", CfarConfig), ("doa", DoaConfig), ("detect", DetectConfig))]
    assert out
    return out


def _builders():
    from blindspot.dsp.config import (BridgeConfig, CfarConfig, DetectConfig, DoaConfig,
                                      EgoMotionConfig)
    from blindspot.radar.config import RadarConfig, SimConfig
    from blindspot.radar.scene import load_scenes
    from blindspot.radar.scenario import load_scenarios
    from blindspot.track.config import TrackerConfig, tracked_recordings
    from blindspot.traj.config import (CalibrationConfig, DatasetConfig, DirectConfig,
                                       EthUcyConfig, EvalConfig, LSTMConfig, TrainConfig,
                                       WalksConfig)

    typed = (RadarConfig, SimConfig, CfarConfig, DoaConfig, DetectConfig, BridgeConfig,
             DatasetConfig, LSTMConfig, TrainConfig, EvalConfig, EthUcyConfig, WalksConfig,
             CalibrationConfig, EgoMotionConfig, TrackerConfig, DirectConfig)
    return {
        **{c.GROUP: c.from_cfg for c in typed},
        "scene": lambda cfg: load_scenes(cfg.scene), "recordings": _build_recordings,
        "scenario": lambda cfg: load_scenarios(cfg.scenario),
        "real_tracking": tracked_recordings,
        "warning": _build_warning,
        "watch": _build_watch,
    }


def _build_watch(cfg):
    from blindspot.report.animation import WatchConfig

    return WatchConfig.from_cfg(cfg)


def _build_warning(cfg):
    from blindspot.safety.config import WarningConfig

    return WarningConfig.from_mapping(cfg.warning)


# Groups that are not library settings: profile only overlays the groups above (both of its
# options are composed below); tracking is read by the MLflow runner glue (blindspot.runs);
# search (a hyper-parameter search, +search=<name>) by the stage runner (blindspot.cli.SearchConfig,
# tests/pipeline/test_launchers.py).
NOT_LIBRARY_GROUPS = {"profile", "runs", "hydra", "search"}


def _options():
    conf = REPO / "conf"
    return sorted((d.name, f.stem) for d in conf.iterdir() if d.is_dir()
                  and d.name not in NOT_LIBRARY_GROUPS for f in d.glob("*.yaml"))


def _default_options():
    defaults = OmegaConf.load(REPO / "conf" / "config.yaml").defaults
    return {next(iter(e.items())) for e in defaults if isinstance(e, Mapping)}


def test_every_group_has_a_typed_builder():
    assert {g for g, _ in _options()} == set(_builders())


# The default option of each group is built from the composed fixture below; every other option
# is composed on its own (one Hydra composition each).
@pytest.mark.parametrize(("group", "option"), [o for o in _options() if o not in _default_options()])
def test_every_option_of_every_group_builds_its_typed_object(group, option):
    cfg = config.compose([f"{group}={option}"], config_dir=REPO / "conf")
    assert _builders()[group](cfg) is not None


def test_the_default_options_build_every_group(composed_config):
    """composed_config: the real conf/ (default option of every group) with the tiny profile."""
    from blindspot.traj.config import TrainConfig

    built = {g: build(composed_config) for g, build in _builders().items()}
    assert all(b is not None for b in built.values())
    assert built["dataset"].n_paths == 16 and built["dataset"].split.train == 1000
    assert TrainConfig.from_cfg(composed_config).epochs == 2


def test_interpolation_keeps_equal_values_equal(composed_config):
    """The equalities that stages once checked by hand now hold by construction in conf/."""
    from blindspot.radar.config import RadarConfig
    from blindspot.traj.config import DatasetConfig, LSTMConfig, TrainConfig

    cfg = config.compose(["radar=dca1000_awr1843", "dataset.window=20"], config_dir=REPO / "conf")
    assert DatasetConfig.from_cfg(cfg).frame_period_s == RadarConfig.from_cfg(cfg).frame_period_s
    assert LSTMConfig.from_cfg(cfg).window == DatasetConfig.from_cfg(cfg).window == 20
    assert TrainConfig.from_cfg(composed_config).seed == DatasetConfig.from_cfg(composed_config).seed == 0


def test_a_bad_override_names_the_dotted_key(composed_config):
    from blindspot.dsp.config import CfarConfig
    from blindspot.typed_config import ConfigError

    cfg = config.compose(["cfar.guard=[2,-1]"], config_dir=REPO / "conf")
    with pytest.raises(ConfigError) as err:
        CfarConfig.from_cfg(cfg)
    assert err.value.key == "cfar.guard" and err.value.value == [2, -1]
    assert "[0, 64]" in str(err.value)
    cfg = config.compose(["+cfar.gaurd=1"], config_dir=REPO / "conf")
    with pytest.raises(ConfigError, match="'cfar.gaurd'"):
        CfarConfig.from_cfg(cfg)
