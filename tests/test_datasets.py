"""The outside data sets (blindspot.datasets): manifest, fetch from a local mirror or a file://
"source", checksums, the stages' up-front check. Never the network."""

import hashlib
import json
import re
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from blindspot import cli, datasets

from .conftest import REPO_ROOT


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


@pytest.fixture()
def fake(tmp_path):
    """A tiny manifest of one set with two data files (one in a folder with a blank in its name)
    and a licence cut from the head of a source file, the "repository" laid out as raw URLs
    under tmp (file://), and a mirror laid out as the shared folder."""
    a, b = b"frame ped x y\n1 2 3.0 4.0\n", bytes(range(256)) * 4
    header = b"/* Copyright TI */\n/* BSD-3-Clause */\nint code;\n"
    repo = tmp_path / "raw" / "someone" / "walks" / "c0ffee"
    for rel, data in (("Data/my walks/a.txt", a), ("Data/b.bin", b), ("src/gtrack.h", header)):
        (repo / rel).parent.mkdir(parents=True, exist_ok=True)
        (repo / rel).write_bytes(data)
    licence = header.splitlines(keepends=True)[:2]
    manifest = {
        "format": 1, "about": "test",
        "url": (tmp_path / "raw").as_uri() + "/{repository}/{commit}/{source}",
        "sets": {"walks": {
            "title": "two walks", "repository": "someone/walks", "commit": "c0ffee",
            "licence": "BSD-3-Clause", "target": "data/walks", "used_by": ["ethucy"],
            "files": [
                {"path": "a.txt", "source": "Data/my walks/a.txt", "size": len(a), "sha256": _sha(a)},
                {"path": "sub/b.bin", "source": "Data/b.bin", "size": len(b), "sha256": _sha(b)},
                {"path": "LICENSE", "source": "src/gtrack.h", "size": len(b"".join(licence)),
                 "sha256": _sha(b"".join(licence)), "licence": True, "head_lines": 2},
            ]}},
    }
    path = tmp_path / "manifest.json"
    path.write_text(json.dumps(manifest))
    mirror = tmp_path / "mirror"
    (mirror / "data/walks/sub").mkdir(parents=True)
    (mirror / "data/walks/a.txt").write_bytes(a)
    (mirror / "data/walks/sub/b.bin").write_bytes(b)
    return path, mirror, {"a.txt": a, "sub/b.bin": b, "LICENSE": b"".join(licence)}


def test_fetch_from_the_source_url_checks_and_keeps_the_licence(fake, tmp_path):
    manifest, _, content = fake
    to = tmp_path / "shared"
    written = datasets.fetch(["walks"], to=to, manifest=manifest, log=lambda *_: None)
    assert len(written) == 3
    for rel, data in content.items():
        assert (to / "data/walks" / rel).read_bytes() == data
    ds = datasets.load_manifest(manifest)["walks"]
    assert datasets.missing_files(ds, to, checksums=True, licences=True) == []
    # a second fetch finds everything in place and writes nothing
    assert datasets.fetch(["walks"], to=to, manifest=manifest, log=lambda *_: None) == []


def test_fetch_from_a_mirror_skips_a_licence_the_mirror_lacks(fake, tmp_path):
    manifest, mirror, content = fake
    to, said = tmp_path / "shared", []
    datasets.fetch([], to=to, mirror=mirror.as_uri(), manifest=manifest, log=said.append)
    assert (to / "data/walks/sub/b.bin").read_bytes() == content["sub/b.bin"]
    assert not (to / "data/walks/LICENSE").exists()
    assert any("has no LICENSE" in s and "without --from" in s for s in said)


def test_a_checksum_mismatch_names_set_source_and_command_and_writes_nothing(fake, tmp_path):
    manifest, mirror, _ = fake
    (mirror / "data/walks/a.txt").write_bytes(b"frame ped x y\n1 2 3.0 4.5\n")  # same size
    to = tmp_path / "shared"
    with pytest.raises(datasets.ChecksumMismatch) as err:
        datasets.fetch(["walks"], to=to, mirror=str(mirror), manifest=manifest,
                       log=lambda *_: None)
    msg = str(err.value)
    assert "walks" in msg and "someone/walks" in msg and "data fetch walks" in msg
    assert not (to / "data/walks/a.txt").exists()


def test_an_unknown_set_is_named(fake, tmp_path):
    with pytest.raises(datasets.DataError, match="unknown data set.*nope.*known: walks"):
        datasets.fetch(["nope"], to=tmp_path, manifest=fake[0])


def test_require_paths_names_the_set_where_and_the_command(fake, tmp_path):
    manifest, mirror, _ = fake
    datasets.require_paths(["data/walks"], mirror, manifest=manifest)  # all there: passes
    (mirror / "data/walks/sub/b.bin").unlink()
    with pytest.raises(datasets.DataMissing) as err:
        datasets.require_paths(["data/walks/a.txt"], mirror, stage="ethucy", manifest=manifest)
    msg = str(err.value)
    assert msg.startswith("stage ethucy: needs the outside data set 'walks'")
    assert "sub/b.bin: absent" in msg and "python -m blindspot data fetch walks" in msg
    with pytest.raises(datasets.DataMissing, match="not a file of the outside data sets"):
        datasets.require_paths(["own/capture.bin"], tmp_path, manifest=manifest)


def test_the_manifest_pins_every_set_with_its_licence_and_its_stages():
    sets = datasets.load_manifest()
    assert set(sets) == {"ethucy", "openradar-presense", "dca1000-awr1843", "ti-gtrack-people",
                         "radhar-walk"}
    stages = set(cli.available_stages(REPO_ROOT))
    for ds in sets.values():
        assert re.fullmatch(r"[0-9a-f]{40}", ds.commit), ds.name
        assert ds.data_files and all(re.fullmatch(r"[0-9a-f]{64}", f.sha256) for f in ds.files)
        assert ds.licence and set(ds.used_by) <= stages
        assert set(ds.used_by) <= set(datasets.STAGE_INPUTS)
        # dca1000-awr1843's repository has no licence file; the manifest says so
        assert any(f.licence for f in ds.files) or "no licence" in ds.licence, ds.name
        assert ds.url(ds.files[0]).startswith(f"https://raw.githubusercontent.com/{ds.repository}/"
                                              f"{ds.commit}/")


def test_the_stages_config_points_into_the_sets(composed_config):
    """Every stage that reads outside data reads paths inside a set of the manifest."""
    targets = [ds.target for ds in datasets.load_manifest().values()]
    for stage in datasets.STAGE_INPUTS:
        paths = datasets.stage_inputs(stage, composed_config)
        assert paths, stage
        for p in paths:
            assert any((p + "/").startswith(t + "/") for t in targets), (stage, p)
    assert datasets.stage_inputs("train", composed_config) == []


def test_a_stage_without_its_data_stops_before_it_runs(tmp_path, monkeypatch):
    monkeypatch.setenv("BLINDSPOT_SHARED", str(tmp_path))
    cfg = OmegaConf.create({"ethucy": {"data": "data/ethucy"}, "paths": {"shared_dir": "x"}})

    def run(cfg, ctx):  # pragma: no cover - must not be reached
        raise AssertionError("the stage ran without its data")

    with pytest.raises(datasets.DataMissing, match="(?s)'ethucy'.*data fetch ethucy"):
        cli.run_stage(run, "ethucy", cfg, REPO_ROOT)


@pytest.mark.real_data
def test_fetch_from_the_shared_mirror_and_check(shared_dir, tmp_path, capsys):
    """The real manifest against the real mirror (file://), for the smallest set."""
    to = tmp_path / "shared"
    assert datasets.main(["fetch", "ti-gtrack-people", "--from", shared_dir.as_uri(),
                          "--to", str(to)]) == 0
    assert datasets.main(["check", "ti-gtrack-people", "--in", str(to)]) == 0
    assert datasets.main(["check", "radhar-walk", "--in", str(to)]) == 2
    out = capsys.readouterr().out
    assert "ti-gtrack-people: ok" in out and "data fetch radhar-walk" in out


def test_help_lists_stages_with_one_line_and_a_stage_its_keys(capsys):
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^  train +the many-to-one LSTM", out, re.M)
    assert re.search(r"^  data +the outside data sets", out, re.M)
    assert cli.main(["real_tracking", "--help"]) == 0
    out = capsys.readouterr().out
    assert "  tracker   (group conf/tracker/:" in out and "radhar-walk" in out
    assert len(out.splitlines()) < 200  # not Hydra's 946 lines


def test_a_bare_info_flag_does_not_swallow_the_overrides():
    """`python -m blindspot train --info` stays available: Hydra's default value is given."""
    assert cli._hydra_argv(["--info", "train.lr=0.1"], "train")[:3] == ["--info", "all",
                                                                        "train.lr=0.1"]
    assert cli._hydra_argv(["--info", "config"], "train")[:2] == ["--info", "config"]
