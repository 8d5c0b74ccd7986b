"""The paper's reference values: each is written in the paper's digest where its source says, and
no other module of the library or the stages types one of the paper's headline numbers."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from blindspot.report import paper_values as paper
from blindspot.report.paper_values import ALL, ETHUCY_CVM, ETHUCY_PUBLISHED, PaperValue

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def digest(shared_dir) -> str:
    """paper/PAPER.md without Markdown bold, whitespace collapsed to single spaces."""
    path = shared_dir / "paper" / "PAPER.md"
    if not path.is_file():
        pytest.skip(f"the paper's digest is not at {path}")
    return re.sub(r"\s+", " ", path.read_text(encoding="utf-8").replace("**", ""))


def as_written(v: PaperValue) -> str:
    """The value as the digest writes it: 20,000; 0.07; 77 GHz; ReLU."""
    text = f"{v.value:,}" if isinstance(v.value, int) else str(v.value)
    return f"{text} {v.unit}" if v.unit else text


def test_every_public_value_is_listed():
    public = {n for n in paper.__all__ if isinstance(getattr(paper, n), PaperValue)}
    assert public == set(ALL)
    assert len(ALL) >= 20


@pytest.mark.parametrize("name", sorted(ALL))
def test_value_is_written_in_the_digest(digest, name):
    value = ALL[name]
    assert as_written(value) in digest, f"{name}: {as_written(value)!r} not in PAPER.md"


@pytest.mark.parametrize("name", sorted(ALL))
def test_source_names_places_of_the_digest(digest, name):
    for part in ALL[name].source.split(";"):
        part = part.strip()
        step = re.fullmatch(r"method step (\d+)", part)
        if step:
            assert re.search(rf"(^| ){step.group(1)}\. [A-Z]", digest), (name, part)
            continue
        place = re.match(r"(Table \d|Fig\. \d+|section [IV]+|Headline numbers)", part)
        assert place, f"{name}: source {part!r} names no table, figure, section or method step"
        assert place.group(1) in digest, (name, part)


def test_ethucy_cvm_is_the_published_average():
    assert ETHUCY_CVM == {"ade": 0.52, "fde": 1.14}
    for rows in ETHUCY_PUBLISHED.values():
        assert "avg" in rows and all(set(r) == {"ade", "fde"} for r in rows.values())


def _constants_outside_docstrings(tree: ast.AST):
    docs = {id(n.value) for n in ast.walk(tree)
            if isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)}
    return [n for n in ast.walk(tree) if isinstance(n, ast.Constant) and id(n) not in docs]


def test_no_other_module_types_the_papers_headline_numbers():
    """0.07 (validation RMSE) and 0.09 (mean path error) live in paper_values only: as numbers,
    or inside strings other than docstrings (prose may cite the paper)."""
    numbers = {paper.VAL_RMSE.value, paper.PATH_ERROR_MEAN_M.value}
    texts = tuple(str(v) for v in numbers)
    own = Path(paper.__file__).resolve()
    found = []
    for root in (REPO / "src", REPO / "stages"):
        for path in sorted(root.rglob("*.py")):
            if path.resolve() == own:
                continue
            for node in _constants_outside_docstrings(ast.parse(path.read_text(encoding="utf-8"))):
                v = node.value
                if (isinstance(v, float) and v in numbers) or (
                        isinstance(v, str) and any(t in v for t in texts)):
                    found.append(f"{path.relative_to(REPO)}:{node.lineno}: {v!r}")
    assert not found, "the paper's numbers typed outside report/paper_values.py:\n" + "\n".join(found)
