"""requirements.lock pins what pyproject.toml asks for, and the environment holds exactly that.

The committed dvc.lock is only reproducible on a fresh clone if the set-up installs the versions it
was made with: `make setup` installs requirements.lock, then the project with ``--no-deps``.
"""

from __future__ import annotations

import importlib.metadata as md
import tomllib

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from packaging.version import Version

from tests.conftest import REPO_ROOT


# Optional extras with a lock file of their own (not part of the default install).
SEPARATE_LOCKS = {"cluster": "requirements-cluster.lock"}


def locked(name: str = "requirements.lock") -> dict[str, Version]:
    pins = {}
    for line in (REPO_ROOT / name).read_text().splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        pkg, sep, version = line.partition("==")
        assert sep and version, f"{name}: {line!r} is not an exact pin (name==version)"
        pins[canonicalize_name(pkg)] = Version(version)
    return pins


def requirements(extra: str | None = None) -> list[Requirement]:
    """pyproject's dependencies and extras (those with no lock of their own); or one extra."""
    project = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["project"]
    extras = project.get("optional-dependencies", {})
    if extra is not None:
        return [Requirement(r) for r in extras[extra]]
    reqs = list(project["dependencies"])
    for name, items in extras.items():
        if name not in SEPARATE_LOCKS:
            reqs += items
    return [Requirement(r) for r in reqs]


def test_separately_locked_extras_are_pinned_within_their_range():
    for extra, lock_file in SEPARATE_LOCKS.items():
        pins = locked(lock_file)
        base = locked()
        assert not set(pins) & set(base), (
            f"{lock_file} re-pins packages of requirements.lock: {sorted(set(pins) & set(base))}")
        for req in requirements(extra):
            name = canonicalize_name(req.name)
            assert name in pins, f"{req} (extra {extra!r}) is not in {lock_file}"
            assert req.specifier.contains(pins[name], prereleases=True), (
                f"{lock_file} pins {name}=={pins[name]}, outside pyproject.toml's {req}")


def test_every_requirement_is_pinned_within_its_range():
    pins = locked()
    for req in requirements():
        name = canonicalize_name(req.name)
        assert name in pins, f"{req} (pyproject.toml) is not in requirements.lock: run `make lock`"
        assert req.specifier.contains(pins[name], prereleases=True), (
            f"requirements.lock pins {name}=={pins[name]}, outside pyproject.toml's {req}: "
            "run `make lock`")


def test_the_environment_holds_the_locked_versions():
    drift = []
    for name, version in locked().items():
        try:
            found = Version(md.version(name))
        except md.PackageNotFoundError:
            drift.append(f"{name}: not installed (locked {version})")
            continue
        if found.public != version.public:  # torch's "+cpu" local label is not part of the pin
            drift.append(f"{name}: {found} installed, {version} locked")
    assert not drift, "the environment differs from requirements.lock (run `make setup`): " + (
        "; ".join(drift))
