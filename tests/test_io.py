"""blindspot.io: outputs appear complete or not at all."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from blindspot import io


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if ".tmp-" in p.name)


def test_failed_write_keeps_previous_file_and_leaves_no_temp(tmp_path: Path) -> None:
    target = tmp_path / "sub" / "a.txt"
    io.write_text(target, "old\n")
    with pytest.raises(RuntimeError):
        with io.atomic_open(target) as fh:
            fh.write("new, half")
            raise RuntimeError("crash mid-write")
    assert target.read_text() == "old\n"
    assert _leftovers(target.parent) == []


def test_temp_file_keeps_the_target_name_in_a_hidden_folder_beside_it(tmp_path: Path) -> None:
    seen = []
    with io.atomic_path(tmp_path / "fig04.png") as tmp:
        seen.append(tmp)
        tmp.write_bytes(b"png")
    # the very name: format sniffing works, and torch.save (which names its archive after the
    # file) writes the same bytes on every run
    assert seen[0].name == "fig04.png" and seen[0].parent.parent == tmp_path
    assert seen[0].parent.name.startswith(".fig04.tmp-") and not seen[0].parent.exists()
    assert _leftovers(tmp_path) == []
    with pytest.raises(FileNotFoundError, match="nothing was written"):
        with io.atomic_path(tmp_path / "empty.bin"):
            pass


def test_torch_save_through_atomic_path_gives_the_same_bytes_twice(tmp_path: Path) -> None:
    torch = pytest.importorskip("torch")
    blobs = []
    for _ in range(2):
        with io.atomic_path(tmp_path / "model.pt") as tmp:
            torch.save({"w": torch.arange(4.0)}, tmp)
        blobs.append((tmp_path / "model.pt").read_bytes())
    assert blobs[0] == blobs[1]


def test_write_json_is_deterministic_numpy_aware_and_rejects_nan(tmp_path: Path) -> None:
    obj = {"b": np.float32(0.5), "a": {"n": np.int64(3), "v": np.arange(3)}, "p": Path("x")}
    io.write_json(tmp_path / "m.json", obj)
    text = (tmp_path / "m.json").read_text()
    assert json.loads(text) == {"a": {"n": 3, "v": [0, 1, 2]}, "b": 0.5, "p": "x"}
    assert text.index('"a"') < text.index('"b"') and text.endswith("}\n")
    io.write_json(tmp_path / "m2.json", dict(reversed(list(obj.items()))))
    assert (tmp_path / "m2.json").read_bytes() == text.encode()
    with pytest.raises(ValueError, match=r"bad.json: \$\.lstm\.ade_m: nan"):
        io.write_json(tmp_path / "bad.json", {"lstm": {"ade_m": float("nan")}})
    assert not (tmp_path / "bad.json").exists()


def test_write_parquet_round_trip(tmp_path: Path) -> None:
    df = pd.DataFrame({"frame": np.arange(4), "x_m": np.linspace(0, 1, 4)})
    path = io.write_parquet(tmp_path / "points.parquet", df)
    pd.testing.assert_frame_equal(pd.read_parquet(path), df)


def test_atomic_dir_replaces_whole_directory_or_nothing(tmp_path: Path) -> None:
    target = tmp_path / "ckpt"
    with io.atomic_dir(target) as d:
        (d / "a").write_text("1")
    with pytest.raises(RuntimeError):
        with io.atomic_dir(target) as d:
            (d / "b").write_text("2")
            raise RuntimeError("crash")
    assert sorted(p.name for p in target.iterdir()) == ["a"]
    with io.atomic_dir(target) as d:
        (d / "c").write_text("3")
    assert sorted(p.name for p in target.iterdir()) == ["c"]
    assert _leftovers(tmp_path) == []


def test_save_figure_png(tmp_path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0, 1], [1, 0])
    path = io.save_figure(fig, tmp_path / "f.png", dpi=50)
    plt.close(fig)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


KILLED_WRITER = """
import sys, time
from pathlib import Path
from blindspot import io
with io.atomic_open(sys.argv[1]) as fh:
    fh.write("partial")
    fh.flush()
    Path(sys.argv[1] + ".go").touch()
    time.sleep(60)
"""


def test_sigkilled_writer_never_exposes_a_partial_file(tmp_path: Path) -> None:
    target = tmp_path / "out.txt"
    proc = subprocess.Popen([sys.executable, "-c", KILLED_WRITER, str(target)])
    deadline = time.time() + 60
    while not Path(str(target) + ".go").exists():
        assert proc.poll() is None and time.time() < deadline
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)  # no handler can run: only the rename protects us
    proc.wait(timeout=30)
    assert not target.exists()


def test_write_yaml_round_trip(tmp_path: Path) -> None:
    from omegaconf import OmegaConf

    plain = {"b": {"x": np.float64(1.5)}, "a": [np.int64(1), 2]}
    path = io.write_yaml(tmp_path / "c.yaml", plain)
    assert path.read_text() == "b:\n  x: 1.5\na:\n- 1\n- 2\n"
    io.write_yaml(tmp_path / "d.yaml", OmegaConf.create({"b": {"x": 1.5}, "a": [1, 2]}))
    assert (tmp_path / "d.yaml").read_bytes() == path.read_bytes()


def test_all_or_none_lands_every_write_together_or_none(tmp_path: Path) -> None:
    a, b, d = tmp_path / "a.txt", tmp_path / "sub" / "b.json", tmp_path / "dir"
    io.write_text(a, "old")
    with pytest.raises(RuntimeError):
        with io.all_or_none():
            io.write_text(a, "new")
            io.write_json(b, {"k": 1})
            with io.atomic_dir(d) as folder:
                io.write_text(folder / "f.txt", "inside")      # inside the folder: at once
            assert a.read_text() == "old" and not b.exists() and not d.exists()  # waiting
            raise RuntimeError("second recording failed")
    assert a.read_text() == "old" and not b.exists() and not d.exists()
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["a.txt", "sub"]      # no temporary
    with io.all_or_none():
        io.write_text(a, "new")
        with io.write_now():
            io.write_text(tmp_path / "ckpt", "epoch 1")
            assert (tmp_path / "ckpt").read_text() == "epoch 1"   # a checkpoint lands at once
        with io.all_or_none():                                     # nested: joins the outer
            io.write_json(b, {"k": 2})
        with io.atomic_dir(d) as folder:
            io.write_text(folder / "f.txt", "inside")
        assert a.read_text() == "old"
    assert a.read_text() == "new" and json.loads(b.read_text()) == {"k": 2}
    assert (d / "f.txt").read_text() == "inside"
    assert not [p for p in tmp_path.rglob("*") if io.TEMP_MARK in p.name]
