"""ETH/UCY loading and Social-GAN windowing; on the real data: the README's window counts and the
published constant-velocity numbers (Schöller et al. 2020), plus a smoke run of the protocol and
its report page."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
from omegaconf import OmegaConf

from blindspot.report.ethucy_report import format_report
from blindspot.report.paper_values import ETHUCY_PUBLISHED
from blindspot.traj.baselines import ConstantVelocity, KalmanCV
from blindspot.traj.ethucy import (
    FOLDS,
    TEST_WINDOWS,
    EthUcyDataError,
    load_split,
    random_rotations,
    read_scene,
    resample_tracks,
    scene_tracks,
    sliding_windows,
)
from blindspot.traj.ethucy_protocol import (
    MODELS,
    EthUcySettings,
    lstm_window_set,
    run_benchmark,
)
from blindspot.traj.config import EthUcyConfig, RolloutLSTMConfig, Seq2SeqConfig
from blindspot.traj.metrics import ade, fde
from blindspot.typed_config import ConfigError

REPO = Path(__file__).resolve().parents[2]


def write_scene(path, rows):
    path.write_text("\n".join("\t".join(f"{v:g}" for v in r) for r in rows) + "\n")
    return path


def synthetic_rows():
    """Pedestrian 1 in frames 0..24, 2 in 0..19, 3 in 3..22 (frame ids step 10, x = frame)."""
    spans = {1: range(0, 25), 2: range(0, 20), 3: range(3, 23)}
    return [(10 * f, p, float(f), float(p)) for p, fr in spans.items() for f in fr]


def test_windows_need_full_presence_and_a_neighbour(tmp_path):
    tracks = scene_tracks(read_scene(write_scene(tmp_path / "s.txt", synthetic_rows())))
    assert tracks.xy.shape == (3, 25, 2)
    # seq_len 20, fully present: ped 1 starts 0..5, ped 2 start 0, ped 3 start 3
    xy, ped, start = sliding_windows(tracks, 20, min_peds=1)
    assert sorted(zip(start.tolist(), tracks.ped_ids[ped].tolist())) == sorted(
        [(s, 1) for s in range(6)] + [(0, 2), (3, 3)])
    # with a neighbour required: start 0 (peds 1, 2) and start 3 (peds 1, 3)
    xy, ped, start = sliding_windows(tracks, 20, min_peds=2)
    assert sorted(zip(start.tolist(), tracks.ped_ids[ped].tolist())) == [
        (0, 1), (0, 2), (3, 1), (3, 3)]
    # windows hold the right positions: x equals the frame index here
    np.testing.assert_array_equal(xy[:, :, 0], start[:, None] + np.arange(20))


def test_a_gap_breaks_the_window(tmp_path):
    rows = [r for r in synthetic_rows() if not (r[1] == 1 and r[0] == 120)]   # ped 1 misses f=12
    tracks = scene_tracks(read_scene(write_scene(tmp_path / "s.txt", rows)))
    _, ped, _ = sliding_windows(tracks, 20, min_peds=1)
    assert 1 not in tracks.ped_ids[ped]


def test_bad_files_are_named(tmp_path):
    with pytest.raises(EthUcyDataError, match="no such"):
        read_scene(tmp_path / "missing.txt")
    bad = tmp_path / "three_columns.txt"
    bad.write_text("0\t1\t2.0\n10\t1\t2.5\n")
    with pytest.raises(EthUcyDataError, match=r"three_columns\.txt.*4 columns"):
        read_scene(bad)
    off = write_scene(tmp_path / "off_grid.txt", [(0, 1, 0, 0), (15, 1, 1, 0)])
    with pytest.raises(EthUcyDataError, match="not on the grid"):
        scene_tracks(read_scene(off), source=str(off))
    dup = write_scene(tmp_path / "dup.txt", [(0, 1, 0, 0), (0, 1, 1, 0)])
    with pytest.raises(EthUcyDataError, match="twice"):
        read_scene(dup)
    with pytest.raises(EthUcyDataError, match="fold"):
        load_split(tmp_path, "nowhere", "test")


def test_resampled_tracks_are_the_walk_at_a_longer_step(tmp_path):
    """A walker at constant velocity, resampled every 5/3 frames, steps 5/3 as far per frame
    and passes exactly through its annotated positions where the grids meet (every 5th
    annotated frame); a pedestrian absent on either side of a resampled time is absent."""
    tracks = scene_tracks(read_scene(write_scene(tmp_path / "s.txt", synthetic_rows())))
    slow = resample_tracks(tracks, 5 / 3)
    assert slow.xy.shape == (3, 15, 2)                  # t = 0, 5/3, ..., 70/3 <= 24
    np.testing.assert_allclose(slow.frames, tracks.frames[0] + 10 * np.arange(15) * 5 / 3)
    ped1 = slow.xy[0]                                    # ped 1: x = frame index, 0..24
    np.testing.assert_allclose(np.diff(ped1[:, 0]), 5 / 3)
    np.testing.assert_array_equal(ped1[::3], tracks.xy[0, ::5][:5])
    np.testing.assert_allclose(ped1[:, 1], 1.0)
    # ped 3 is annotated in frames 3..22: present at t in [3, 22] only
    t = np.arange(15) * 5 / 3
    np.testing.assert_array_equal(np.isfinite(slow.xy[2, :, 0]), (t >= 3 - 1e-9) & (t <= 22))
    assert resample_tracks(tracks, 1) is tracks
    for bad in (0.5, float("nan"), "fast", "2", True, None, [1, 2]):
        with pytest.raises(EthUcyDataError, match=r"step: expected a finite number >= 1 .*"
                           r"found " + re.escape(repr(bad))):
            resample_tracks(tracks, bad)


def test_resampled_edges_follow_the_annotated_frames(tmp_path):
    """At step 5/3 the grids meet every 5 annotated frames: a track ending on such a frame is
    present there, one ending just before it is absent there (its next frame is missing), and
    one starting just after a resampled time is absent at that time. At step 1.4, times such
    as 7 x 1.4 = 9.799... and 5 x 1.4 = 7.0 land on their annotated frames."""
    spans = {1: range(0, 21), 2: range(0, 20), 3: range(6, 22)}     # the scene: frames 0..21
    rows = [(10 * f, p, float(f), float(p)) for p, fr in spans.items() for f in fr]
    tracks = scene_tracks(read_scene(write_scene(tmp_path / "s.txt", rows)))
    slow = resample_tracks(tracks, 5 / 3)               # t = 0, 5/3, ..., 20: 13 times
    present = np.isfinite(slow.xy[..., 0])
    assert present[0].all() and slow.xy[0, -1, 0] == 20.0     # ends on t = 20: present,
    #                                                           though frame 21 holds nothing
    assert present[1, :-1].all() and not present[1, -1]        # ends at 19 < 20
    t = np.arange(13) * 5 / 3
    np.testing.assert_array_equal(present[2], t >= 6)          # starts at 6: absent at 5
    np.testing.assert_allclose(slow.xy[2, present[2], 0], t[t >= 6])
    odd = resample_tracks(tracks, 1.4)
    np.testing.assert_allclose(odd.xy[0, :15, 0], np.arange(15) * 1.4, rtol=0, atol=1e-12)
    assert np.isfinite(odd.xy[1, :14, 0]).all()               # 13 x 1.4 = 18.2 < 19


def test_the_benchmark_resamples_the_train_split_alone(tmp_path, monkeypatch):
    """The stage's learned models train on windows at every configured step; their val and
    test windows are read as annotated."""
    import blindspot.traj.ethucy_protocol as protocol

    seen = []
    real = protocol.load_split

    def spy(data_dir, fold, split, **kw):
        seen.append((split, tuple(kw.get("time_steps", (1.0,)))))
        return real(data_dir, fold, split, **kw)

    monkeypatch.setattr(protocol, "load_split", spy)
    cfg = Seq2SeqConfig(epochs=1, ensemble=1, neighbours=0, time_steps=(1.0, 5 / 3))
    for split in ("train", "val", "test"):
        d = tmp_path / "eth" / split
        d.mkdir(parents=True)
        write_scene(d / "a.txt", [(10 * f, p, 0.5 * f, float(p)) for p in (1, 2)
                                  for f in range(40)])
    protocol.run_fold(tmp_path, "eth", ("lstm",), RolloutLSTMConfig(), progress=False,
                      seq2seq=cfg)
    assert ("train", (1.0, 5 / 3)) in seen
    assert {steps for split, steps in seen if split != "train"} == {(1.0,)}


def test_a_split_at_several_time_steps_pools_their_windows(tmp_path):
    """Per file, the windows at step 1 are the split's own, followed by those of the resampled
    scene; the resampled windows cover step x 19 annotated frames and keep their pedestrians'
    ids, with neighbours read on the resampled grid; the file's skip report is the annotated
    grid's alone; a tuple without step 1 is refused, by load_split and by the config."""
    d = tmp_path / "eth" / "train"
    d.mkdir(parents=True)
    rows = [(10 * f, p, 0.5 * f, float(p)) for p in (1, 2) for f in range(40)]
    write_scene(d / "a.txt", rows)
    own = load_split(tmp_path, "eth", "train", min_peds=1)
    both = load_split(tmp_path, "eth", "train", min_peds=1, time_steps=(1.0, 2.0), neighbours=1)
    assert len(own) == 2 * 21 and len(both) == 2 * 21 + 2 * 1
    assert sorted(both.track_id[len(own):].tolist()) == sorted(set(own.track_id.tolist()))
    # the one neighbour is the other pedestrian (y = 1 and 2), over the resampled observed frames
    np.testing.assert_allclose(both.neighbours[len(own):, 0, :, :],
                               np.stack([both.xy[len(own):, :8, 0],
                                         3 - both.xy[len(own):, :8, 1]], axis=-1))
    np.testing.assert_array_equal(both.xy[:len(own)], own.xy)
    np.testing.assert_allclose(np.diff(both.xy[len(own):, :, 0], axis=1), 1.0)   # 2 x 0.5 m
    assert both.skipped == own.skipped
    for bad in ((2.0,), (1.0, 1.0), (1.0, 2.0, 2.0)):
        with pytest.raises(EthUcyDataError, match="time_steps: expected distinct steps holding 1"):
            load_split(tmp_path, "eth", "train", time_steps=bad)
        with pytest.raises(ConfigError, match="time_steps"):
            Seq2SeqConfig(time_steps=bad)
    with pytest.raises(EthUcyDataError, match=r"time_steps\[1\]: expected a finite number"):
        load_split(tmp_path, "eth", "train", time_steps=(1.0, 0.5))
    with pytest.raises(EthUcyDataError, match="time_steps: expected a tuple or list"):
        load_split(tmp_path, "eth", "train", time_steps=2.0)


def test_transformer_heads_are_checked_when_a_model_uses_them():
    """The group's seq2seq.cell is set per model key, so the heads are checked against the
    width when the models (or mix_cell) name the transformer, by the key's name."""
    from blindspot.typed_config import ConfigError

    group = OmegaConf.to_container(OmegaConf.load(REPO / "conf" / "ethucy" / "standard.yaml"))
    group["seq2seq"]["attention_heads"] = 3
    EthUcyConfig.from_mapping(group)                           # no transformer: not read
    for change in ({"models": ["cvm", "transformer"]}, {"mix_cell": "transformer"}):
        with pytest.raises(ConfigError, match="seq2seq.attention_heads.*divisor of"):
            EthUcyConfig.from_mapping({**group, **change})


def test_settings_from_the_config_group(tmp_path):
    """conf/ethucy/standard.yaml, typed (EthUcyConfig), gives the run's settings: data under the
    shared folder, the top-level seed and ethucy.threads in both learned models' settings, the
    next-point LSTM's settings the typed defaults (conf/ holds the same values)."""
    from dataclasses import replace

    group = OmegaConf.load(REPO / "conf" / "ethucy" / "standard.yaml")
    settings = EthUcySettings.from_config(EthUcyConfig.from_mapping(group), shared_dir=tmp_path,
                                          seed=7)
    assert (settings.models, settings.folds, settings.data_dir, settings.calibration) == (
        tuple(group.models), tuple(group.folds), tmp_path / group.data, group.calibration)
    assert settings.seq2seq.seed == settings.lstm.seed == 7
    assert settings.seq2seq.threads == settings.lstm.num_threads == group.threads
    assert replace(settings.lstm, seed=0, num_threads=None) == RolloutLSTMConfig()


def test_the_rollout_lstm_settings_name_the_bad_key():
    with pytest.raises(ConfigError, match="ethucy.lstm_rollout.rotations"):
        RolloutLSTMConfig.from_mapping({"frame": "heading", "rotations": 2})
    with pytest.raises(ConfigError, match="ethucy.lstm_rollout.ensemble"):
        RolloutLSTMConfig.from_mapping({"ensemble": 0})


def test_scale_augmentation_with_a_speed_scaled_frame_is_refused():
    """The speed-scaled frame divides the scale out, so the combination would only train on
    windows whose last step sits at the floor: refused, naming the key."""
    with pytest.raises(ConfigError, match="ethucy.seq2seq.scale_aug.*speed_floor"):
        Seq2SeqConfig.from_mapping({"scale_aug": 0.15, "speed_floor": 0.05})
    assert Seq2SeqConfig.from_mapping({"scale_aug": 0.15}).scale_aug == 0.15


def test_random_rotations_keep_shape_of_motion():
    rng = np.random.default_rng(0)
    xy = np.cumsum(rng.normal(size=(50, 9, 2)), axis=1)
    rot = random_rotations(xy, 3, np.random.default_rng(1))
    assert rot.shape == (150, 9, 2)
    for copy in range(3):
        r = rot[copy * 50:(copy + 1) * 50]
        np.testing.assert_allclose(np.linalg.norm(r, axis=-1), np.linalg.norm(xy, axis=-1))
        np.testing.assert_allclose(np.linalg.norm(np.diff(r, axis=1), axis=-1),
                                   np.linalg.norm(np.diff(xy, axis=1), axis=-1))
    assert not np.allclose(rot[:50], xy)
    np.testing.assert_array_equal(rot, random_rotations(xy, 3, np.random.default_rng(1)))


# ---------------------------------------------------------------------------- real data


@pytest.fixture(scope="module")
def ethucy_dir(shared_dir):
    d = shared_dir / "data" / "ethucy"
    if not (d / "eth" / "test").is_dir():
        pytest.skip(f"ETH/UCY data not found at {d}")
    return d


@pytest.fixture(scope="module")
def test_windows(ethucy_dir):
    return {fold: load_split(ethucy_dir, fold, "test") for fold in FOLDS}


@pytest.mark.real_data
@pytest.mark.parametrize("fold", FOLDS)
def test_test_window_counts_match_the_readme(test_windows, fold):
    assert len(test_windows[fold]) == TEST_WINDOWS[fold]
    assert np.isfinite(test_windows[fold].xy).all()


@pytest.mark.real_data
def test_constant_velocity_reproduces_the_published_numbers(test_windows):
    cvm, scores = ConstantVelocity(), {}
    for fold, w in test_windows.items():
        pred = cvm.predict(w.observed(), 12)
        scores[fold] = (ade(pred, w.future()), fde(pred, w.future()))
    published = ETHUCY_PUBLISHED["cvm (Schöller et al. 2020)"]
    for fold, (a, f) in scores.items():    # published to two decimals: within half a unit + 0.005
        assert abs(a - published[fold]["ade"]) <= 0.01, (fold, a)
        assert abs(f - published[fold]["fde"]) <= 0.01, (fold, f)
    avg = np.mean(list(scores.values()), axis=0)
    assert abs(avg[0] - 0.52) <= 0.01 and abs(avg[1] - 1.14) <= 0.01, avg


@pytest.mark.real_data
def test_protocol_smoke_on_the_eth_fold(ethucy_dir):
    run = run_benchmark(EthUcySettings(ethucy_dir, models=("cvm", "kalman"), folds=("eth",)),
                        progress=False)
    result = run.results
    assert set(result) == {"cvm", "kalman", "best"} and result["best"] in ("cvm", "kalman")
    for model in (result["cvm"], result["kalman"]):
        assert set(model) == {"eth", "avg"}
        assert model["eth"]["n_windows"] == 181
        assert model["avg"]["ade"] == model["eth"]["ade"]
        assert 0 < model["eth"]["ade"] < model["eth"]["fde"] < 5
    assert result["cvm"]["eth"]["ade"] == pytest.approx(1.00, abs=0.01)
    # the validation scores and details are the plain dicts the report page reads
    assert set(run.validation()["cvm"]) == {"eth", "avg"}
    assert run.details()["eth"]["cvm"]["n_windows"] == 181
    json.dumps(run.details())   # plain values only
    text = format_report(result, run.validation(), run.details(), ("eth",), None,
                         "python -m blindspot ethucy", None)
    assert "| cvm (ours) |" in text and "published" in text
    assert "Fitted process noise q (m^2/s^3), meas_std 0.05 m: eth " in text


@pytest.mark.real_data
def test_lstm_training_pairs_cover_every_nine_frame_stretch(ethucy_dir):
    stretches = load_split(ethucy_dir, "eth", "val", seq_len=9, min_peds=1)
    heading = lstm_window_set(ethucy_dir, "eth", "val", RolloutLSTMConfig(mirror=True))
    world = lstm_window_set(ethucy_dir, "eth", "val",
                            RolloutLSTMConfig(frame="world", rotations=2, mirror=False))
    assert len(heading) == 2 * len(stretches) and len(world) == 3 * len(stretches)
    np.testing.assert_allclose(world.x[: len(stretches)], stretches.xy[:, :8], atol=1e-5)
    # heading frame: last input at the origin, last step along +x, target = CVM correction
    np.testing.assert_allclose(heading.x[:, -1], 0.0, atol=1e-5)
    np.testing.assert_allclose(heading.x[:, -2, 1], 0.0, atol=1e-5)
    speed = np.linalg.norm(stretches.xy[:, 7] - stretches.xy[:, 6], axis=-1)
    step_next = np.linalg.norm(stretches.xy[:, 8] - stretches.xy[:, 7], axis=-1)
    next_in_frame = heading.y[: len(stretches)].astype(float)
    next_in_frame[:, 0] += speed                 # undo the residual: add the last step (speed, 0)
    np.testing.assert_allclose(np.linalg.norm(next_in_frame, axis=-1), step_next, atol=1e-4)


@pytest.mark.real_data
def test_protocol_trains_and_scores_the_lstm(ethucy_dir):
    lstm = RolloutLSTMConfig(epochs=1, ensemble=2, num_threads=1)
    run = run_benchmark(EthUcySettings(ethucy_dir, models=("cvm", "lstm_rollout"), folds=("eth",),
                                       lstm=lstm), progress=False)
    result = run.results["lstm_rollout"]
    assert result["eth"]["n_windows"] == 181
    assert 0.5 < result["eth"]["ade"] < 2.0     # CVM: 1.00; a broken predictor lands far outside


@pytest.mark.real_data
def test_each_direct_model_key_trains_its_own_encoder(ethucy_dir):
    """The model keys lstm / gru / mlp / transformer train the direct predictor with an LSTM /
    GRU / dense / self-attention encoder (one member, one epoch on fold eth) and score it like
    any other model."""
    from dataclasses import replace as _replace

    import torch

    from blindspot.traj import ethucy_protocol
    from blindspot.traj.config import Seq2SeqConfig

    trained = {}
    real = ethucy_protocol.train_fold_seq2seq

    def spy(data_dir, fold, cfg, name, progress=False, **kw):
        ens, fitted = real(data_dir, fold, cfg, name, progress, **kw)
        trained[name] = ens.members[0].net.encoder
        return ens, fitted

    cfg = _replace(Seq2SeqConfig(), epochs=1, ensemble=1, neighbours=0)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(ethucy_protocol, "train_fold_seq2seq", spy)
        out = ethucy_protocol.run_fold(ethucy_dir, "eth", ("lstm", "gru", "mlp", "transformer"),
                                        RolloutLSTMConfig(), progress=False, seq2seq=cfg,
                                        calibration="mle")
    assert isinstance(trained["lstm"], torch.nn.LSTM)
    assert isinstance(trained["gru"], torch.nn.GRU)
    assert isinstance(trained["mlp"], torch.nn.Sequential)
    assert isinstance(trained["transformer"], torch.nn.TransformerEncoder)
    for name in ("lstm", "gru", "mlp", "transformer"):
        assert 0.5 < out[name].ade < 2.0                        # CVM: 1.00 on eth
        assert 0.0 < out[name].calibration["coverage_90"] <= 1.0


def test_neighbours_are_the_nearest_others_over_the_observed_frames_only(tmp_path):
    """Five pedestrians on parallel lines y = 0, 1, 3, -0.5, 10 (x = frame), one absent after
    frame 5: each window's neighbours are the others sorted by distance at its last observed
    frame, their positions over the observed frames only, NaN where absent or missing."""
    from blindspot.traj.ethucy import neighbour_tracks

    F = 30
    ys = np.array([0.0, 1.0, 3.0, -0.5, 10.0])
    xy = np.stack([np.broadcast_to(np.arange(F, dtype=float), (5, F)),
                   np.broadcast_to(ys[:, None], (5, F))], axis=-1).copy()
    xy[4, 6:] = np.nan                                # pedestrian 4 leaves after frame 5
    tracks = scene_tracks(np.array([(10 * f, p, *xy[p, f]) for p in range(5) for f in range(F)
                                    if np.isfinite(xy[p, f, 0])]))
    nb = neighbour_tracks(tracks, np.array([0, 0, 2]), np.array([0, 10, 10]), k=5, obs_len=8)
    assert nb.shape == (3, 5, 8, 2)
    # window 0 (ped 0, frames 0-7): ped 4 is absent at the last observed frame, so it is no
    # neighbour; the others sorted by distance are 3, 1, 2; the last two slots stay empty
    np.testing.assert_allclose(nb[0, :3, :, 1], np.broadcast_to([[-0.5], [1.0], [3.0]], (3, 8)))
    np.testing.assert_allclose(nb[0, 0, :, 0], np.arange(8.0))       # observed frames only
    assert np.isnan(nb[0, 3:]).all()
    # window 2 (ped 2 at y = 3, frames 10-17): 1 (2 m), 0 (3 m), 3 (3.5 m)
    np.testing.assert_allclose(nb[2, :3, -1, 1], [1.0, 0.0, -0.5])
    (tmp_path / "eth" / "val").mkdir(parents=True)
    write_scene(tmp_path / "eth" / "val" / "s.txt", synthetic_rows())
    w = load_split(tmp_path, "eth", "val", min_peds=1, neighbours=2)
    assert w.neighbours.shape == (len(w), 2, 8, 2)
    # synthetic_rows: y = pedestrian id; ped 1's window at start 0 has 2 (1 m away) and 3
    # (2 m away, present from frame 3 on) as neighbours, nearest first
    first = np.flatnonzero((w.start == 0) & (w.xy[:, 0, 1] == 1.0))[0]
    np.testing.assert_allclose(w.neighbours[first, :, -1, 1], [2.0, 3.0])
    assert np.isnan(w.neighbours[first, 1, :3]).all()          # 3 appears at frame 3


def _scores(per_fold):
    """Everything a run reports per fold and model but its wall seconds (the item's and the
    fitted training's, ``train_seconds``)."""
    return {fold: {m: (o.ade, o.fde, o.n_windows,
                       json.dumps({k: v for k, v in o.fitted.items() if not k.endswith("seconds")},
                                  sort_keys=True, default=str),
                       json.dumps(o.calibration, sort_keys=True, default=str))
                   for m, o in r.items()} for fold, r in per_fold.items()}


def test_benchmark_items_put_the_learned_models_first():
    from blindspot.traj.ethucy_protocol import benchmark_items

    items = benchmark_items(("cvm", "kalman", "lstm", "mlp", "gru", "transformer"),
                            ("eth", "hotel"))
    assert items == [("eth", "transformer"), ("hotel", "transformer"),
                     ("eth", "lstm"), ("hotel", "lstm"), ("eth", "gru"), ("hotel", "gru"),
                     ("eth", "mlp"), ("hotel", "mlp"),
                     ("eth", "kalman"), ("hotel", "kalman"), ("eth", "cvm"), ("hotel", "cvm")]


@pytest.mark.real_data
def test_scores_do_not_depend_on_the_workers_or_on_the_models_run_together(ethucy_dir):
    """(fold, model) items in 2 processes = 1 process = each fold's models in one run_fold."""
    from blindspot.traj.ethucy_protocol import run_fold

    s = EthUcySettings(ethucy_dir, models=("cvm",), folds=("eth", "hotel"), calibration="mle")
    one, two = (run_benchmark(s, progress=False, jobs=j) for j in (1, 2))
    grouped = {f: run_fold(ethucy_dir, f, s.models, s.lstm, progress=False, seq2seq=s.seq2seq,
                           calibration=s.calibration, speed_edges=s.speed_edges)
               for f in s.folds}
    assert _scores(one.per_fold) == _scores(two.per_fold) == _scores(grouped)
    assert one.results == two.results
    assert list(one.per_fold) == ["eth", "hotel"] and list(one.per_fold["eth"]) == ["cvm"]


@pytest.mark.slow
@pytest.mark.real_data
def test_learned_scores_do_not_depend_on_the_workers_or_on_the_models_run_together(ethucy_dir):
    """Kalman's fit and the seeded direct predictors (one epoch) give the same scores and fits
    whether a fold's models run in one process or as (fold, model) items over 2 workers."""
    from dataclasses import replace as _replace

    from blindspot.traj.config import Seq2SeqConfig
    from blindspot.traj.ethucy_protocol import run_fold

    s = EthUcySettings(ethucy_dir, models=("cvm", "kalman", "lstm", "gru", "mlp"), folds=("eth",),
                       seq2seq=_replace(Seq2SeqConfig(), epochs=1), calibration="conditional")
    two = run_benchmark(s, progress=False, jobs=2)
    grouped = {f: run_fold(ethucy_dir, f, s.models, s.lstm, progress=False, seq2seq=s.seq2seq,
                           calibration=s.calibration, speed_edges=s.speed_edges)
               for f in s.folds}
    assert _scores(two.per_fold) == _scores(grouped)


@pytest.mark.real_data
def test_the_online_setting_is_chosen_on_the_folds_val_scenes_alone(ethucy_dir):
    """Fold eth, Kalman, two candidate settings: the one scored on the test scene is the one
    :func:`select_on_held_out_streams` picks from the fold's val windows alone (each val scene
    met as a new scene), and the metrics name it with its val distance and carry a bootstrap
    interval over the test pedestrians around the coverage."""
    from blindspot.traj.conformal import AdaptiveConformal, select_on_held_out_streams
    from blindspot.traj.distribution import mahalanobis_sq
    from blindspot.traj.ethucy_protocol import (CALIBRATION_LEVELS, reveal_times, run_fold,
                                                 val_windows)

    candidates = (AdaptiveConformal(CALIBRATION_LEVELS, 0.005, 100),
                  AdaptiveConformal(CALIBRATION_LEVELS, 0.005, 100, 3))
    s = EthUcySettings(ethucy_dir, models=("kalman",), folds=("eth",), calibration="mle")
    calib = run_fold(ethucy_dir, "eth", s.models, s.lstm, progress=False, seq2seq=s.seq2seq,
                     calibration=s.calibration, online=candidates)["kalman"].calibration
    val = val_windows(ethucy_dir, "eth", 0)
    kalman = KalmanCV().fit(load_split(ethucy_dir, "eth", "train").xy, objective="forecast",
                            obs_len=8)
    d2 = mahalanobis_sq(kalman.predict_distribution(val.observed(), 12), val.future())
    best, table = select_on_held_out_streams(candidates, d2, *reveal_times(val.start),
                                             val.file_index)
    chosen = candidates[best]
    assert (calib["online_gamma"], calib["online_window"], calib["online_rescale_after"]) == \
        (chosen.gamma, chosen.window, chosen.rescale_prior_after)
    assert calib["online_val_distance"] == pytest.approx(table[best].distance_mean)
    for p in (50, 90, 95):
        lo, hi = calib[f"online_coverage_{p}_ci95"]
        assert lo <= calib[f"online_coverage_{p}"] <= hi


def _outcome(seed_rows):
    from blindspot.traj.ethucy_protocol import FoldOutcome

    a = float(np.mean([r["ade"] for r in seed_rows]))
    f = float(np.mean([r["fde"] for r in seed_rows]))
    return FoldOutcome(a, f, 10, 1.0, {"seed_scores": seed_rows, "val_ade_m": a,
                                       "val_fde_m": f})


def test_seeds_and_best_of_blocks_are_the_seeds_mean_and_sample_sd():
    """Issue 43: ethucy.json's "seeds" block holds each seed's fold-averaged ADE / FDE, their
    mean and sample sd (ddof 1), "best_of_20" the fold rows' seed means and their average;
    models without seed rows (cvm) get neither."""
    from blindspot.traj.ethucy_protocol import FoldOutcome, summarise

    ade = {"eth": [0.9, 0.8, 1.0], "hotel": [0.3, 0.4, 0.2]}
    per_fold = {}
    for f, vals in ade.items():
        rows = [{"ade": v, "fde": 2 * v, "best_of_ade": v / 4, "best_of_fde": v / 2,
                 "best_of_n": 20} for v in vals]
        per_fold[f] = {"mix": _outcome(rows),
                       "cvm": FoldOutcome(1.0, 2.0, 10, 1.0, {"val_ade_m": 0.5, "val_fde_m": 1.0})}
    out = summarise(per_fold, ("cvm", "mix"))
    per_seed = [(0.9 + 0.3) / 2, (0.8 + 0.4) / 2, (1.0 + 0.2) / 2]     # 0.6 each
    assert out["seeds"]["mix"]["ade"] == pytest.approx(per_seed)
    assert out["seeds"]["mix"]["ade_mean"] == pytest.approx(0.6)
    assert out["seeds"]["mix"]["ade_sd"] == pytest.approx(0.0, abs=1e-12)
    assert out["mix"]["avg"]["ade"] == pytest.approx(out["seeds"]["mix"]["ade_mean"])
    assert "cvm" not in out["seeds"] and out["best"] == "cvm"
    b = out["best_of_20"]["mix"]
    assert b["eth"]["ade"] == pytest.approx(0.9 / 4) and b["hotel"]["fde"] == pytest.approx(0.15)
    assert b["avg"]["ade"] == pytest.approx((0.9 + 0.3) / 8)
    # a spread the sd must see: seeds 0.5 / 0.7 on one fold -> sd of (0.5, 0.7) = 0.1414
    two = {"eth": {"mix": _outcome([{"ade": 0.5, "fde": 1.0}, {"ade": 0.7, "fde": 1.4}])}}
    s = summarise(two, ("mix",))["seeds"]["mix"]
    assert s["ade_sd"] == pytest.approx(np.std([0.5, 0.7], ddof=1))
    assert s["fde_mean"] == pytest.approx(1.2) and "best_of_20" not in summarise(two, ("mix",))


@pytest.mark.real_data
def test_the_multi_modal_model_is_scored_best_of_20_over_its_seeds(ethucy_dir):
    """mix on fold eth, two seeds, one epoch: the fold's ADE is the seeds' mean, best-of-20
    beats the single prediction (the nearest of 20 hypotheses), the point is chosen on val,
    and the calibration scores its moment-matched Gaussian."""
    from blindspot.traj.config import Seq2SeqConfig
    from blindspot.traj.ethucy_protocol import run_fold

    cfg = Seq2SeqConfig(epochs=1, ensemble=1, neighbours=0, threads=1)
    out = run_fold(ethucy_dir, "eth", ("mix",), RolloutLSTMConfig(), progress=False,
                   seq2seq=cfg, calibration="mle", seeds=2)["mix"]
    rows = out.fitted["seed_scores"]
    assert [r["seed"] for r in rows] == [0, 1]
    assert out.ade == pytest.approx(np.mean([r["ade"] for r in rows]))
    for r in rows:
        assert r["best_of_n"] == 20 and r["point"] in ("mean", "mode")
        assert 0.1 < r["best_of_ade"] < r["ade"] and r["best_of_fde"] < r["fde"]
        assert 0.0 < r["mixture_coverage_50"] < r["mixture_coverage_90"] <= 1.0
    assert 0.0 < out.calibration["online_coverage_90"] <= 1.0
