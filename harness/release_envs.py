"""One isolated Python environment per engine release, created once and
kept in a cache folder (`mechval matrix`, docs/comparison.md, "The release
matrix").

An environment is a plain `venv` (no system site-packages: the engine
installed beside the caller's mechval is not visible in it) holding the
requested engine release, this mechval (a wheel built from its source
tree, installed without dependencies) and mechval's pinned dependencies
less every engine library (so that mechval's own pin of, say, MuJoCo does
not decide the release). It lives in

    ENVS/<distribution>-<version>-py<X.Y>/      the venv
    ENVS/<distribution>-<version>-py<X.Y>/mechval-env.json   what it holds

and is reused while that record matches: the same pins and engine
release; a changed mechval only reinstalls the wheel. The record is
written last, so an environment whose creation was interrupted or failed
is created again, never used. pip runs from the caller's environment
(`pip --python`), with the environment variables that would put other
packages on the path (PYTHONPATH and the user site) removed; so does
every process started in the environment.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import importlib.metadata
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
import venv
import zipfile
from dataclasses import dataclass
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

import mechval
from mechval.engines import registry

#: The record of what an environment holds, written when it is complete.
RECORD = "mechval-env.json"
#: Seconds pip may take to create one environment (downloads included).
INSTALL_TIMEOUT = 1800.0


class ReleaseUnavailable(RuntimeError):
    """An engine release that cannot be installed here: its reason."""


def default_envs_dir() -> Path:
    """~/.cache/mechval/envs, or under $XDG_CACHE_HOME where set."""
    cache = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(cache) / "mechval" / "envs"


def clean_environ() -> dict[str, str]:
    """This process's environment without what would put other packages on
    a child's path: PYTHONPATH, PYTHONHOME, PYTHONSTARTUP, the user site."""
    kept = {k: v for k, v in os.environ.items()
            if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "PYTHONUSERBASE", "VIRTUAL_ENV")}
    return {**kept, "PYTHONNOUSERSITE": "1"}


def engine_distribution(engine: str) -> str:
    """The distribution of `engine`'s library (the adapter's
    `distribution`, read without importing the engine)."""
    return registry.library_and_distribution(engine)[1]


def plugin_requirement(engine: str) -> str | None:
    """`DIST==VERSION` of the plug-in distribution that registers `engine`,
    when it is neither mechval nor the engine library itself (an adapter
    shipped apart from its engine): the environment needs it too."""
    for entry in importlib.metadata.entry_points(group=registry.ENTRY_POINT_GROUP):
        dist = getattr(entry, "dist", None)
        if entry.name == engine and dist is not None:
            name = canonicalize_name(dist.name)
            if name in (canonicalize_name(registry.OWN_DISTRIBUTION), canonicalize_name(engine_distribution(engine))):
                return None
            return f"{dist.name}=={dist.version}"
    return None


def pinned_requirements() -> list[str]:
    """mechval's own requirements (no extras) less every registered
    engine's library: what an environment holds besides the engine."""
    engines = set()
    for name in registry.engine_names():
        try:
            engines.add(canonicalize_name(engine_distribution(name)))
        except (ImportError, registry.EngineUnavailable):
            continue            # an adapter that does not import names no library to leave out
    kept = []
    for text in importlib.metadata.requires(registry.OWN_DISTRIBUTION) or []:
        requirement = Requirement(text)
        if requirement.marker is not None and "extra" in str(requirement.marker):
            continue
        if canonicalize_name(requirement.name) not in engines:
            kept.append(text)
    return kept


def source_tree() -> Path:
    """The folder this mechval was installed from (its pyproject.toml
    names the project "mechval"); ReleaseUnavailable when there is none."""
    root = Path(mechval.__file__).resolve().parent.parent
    try:
        project = tomllib.loads((root / "pyproject.toml").read_text(encoding="utf-8"))["project"]["name"]
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        project = None
    if project != registry.OWN_DISTRIBUTION:
        raise ReleaseUnavailable(f"no mechval source tree beside {mechval.__file__} to build this mechval from")
    return root


def build_wheel(folder: Path) -> Path:
    """A wheel of this mechval, built in `folder` from a copy of its source
    (pyproject.toml and the package folders it names), so that the build
    writes nothing into the source tree."""
    source = source_tree()
    pyproject = source / "pyproject.toml"
    copy = Path(folder) / "source"
    copy.mkdir(parents=True)
    shutil.copy2(pyproject, copy)
    layout = tomllib.loads(pyproject.read_text(encoding="utf-8"))["tool"]["setuptools"]["package-dir"]
    for top in {Path(d).parts[0] for d in layout.values()}:
        shutil.copytree(source / top, copy / top, ignore=shutil.ignore_patterns("__pycache__", "out"))
    command = [sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "-w", str(folder), str(copy)]
    if importlib.util.find_spec("setuptools"):
        command.insert(-1, "--no-build-isolation")     # no download of a build backend
    _pip(command, "build this mechval's wheel")
    return next(Path(folder).glob("mechval-*.whl"))


def wheel_digest(wheel: Path) -> str:
    """sha256 of the wheel's members (names and contents), not of the zip
    file, whose time stamps change with every build."""
    digest = hashlib.sha256()
    with zipfile.ZipFile(wheel) as archive:
        for name in sorted(archive.namelist()):
            digest.update(name.encode() + b"\0" + archive.read(name))
    return digest.hexdigest()[:16]


@dataclass(frozen=True)
class Release:
    """What one environment holds: the engine release and the rest."""

    distribution: str
    version: str
    #: mechval's pins less the engines, and a separate adapter's plug-in.
    requirements: tuple[str, ...]
    #: Extra places pip looks for distributions (--find-links).
    find_links: tuple[str, ...] = ()

    @property
    def folder_name(self) -> str:
        python = f"py{sys.version_info.major}.{sys.version_info.minor}"
        return f"{canonicalize_name(self.distribution)}-{self.version}-{python}"

    def record(self, mechval_digest: str) -> dict:
        return {"engine": f"{self.distribution}=={self.version}", "requirements": list(self.requirements),
                "python": sys.version.split()[0], "mechval": mechval_digest}


def python_of(env: Path) -> Path:
    return Path(env) / "bin" / "python"


def ensure_env(envs: Path, release: Release, wheel: Path, digest: str) -> Path:
    """The environment of `release` under `envs`, with this mechval
    (`wheel`, `digest`): reused, refreshed (a changed mechval) or created;
    ReleaseUnavailable with pip's reason when the release cannot be
    installed. One process at a time works on an environment (a lock file
    beside it). A new environment starts as a copy of the pins' own
    (`_pinned_env`, hard links where the file system has them), so that
    pip installs only the release and what it needs beyond the pins."""
    envs.mkdir(parents=True, exist_ok=True)
    env = envs / release.folder_name
    with _locked(envs, release.folder_name):
        held = _read_record(env)
        wanted = release.record(digest)
        if held is not None and {**held, "mechval": digest} == wanted:
            if held["mechval"] != digest:
                _install_mechval(env, wheel)
                _write_record(env, wanted)
            return env
        pins = _pinned_env(envs, release)
        shutil.rmtree(env, ignore_errors=True)
        try:
            venv.EnvBuilder(with_pip=False, symlinks=True, clear=True).create(env)
            _link_tree(_site_packages(pins), _site_packages(env))
            links = [arg for place in release.find_links for arg in ("--find-links", place)]
            _pip(_pip_install(env) + links + [*release.requirements, f"{release.distribution}=={release.version}"],
                 f"install {release.distribution} {release.version}")
            _install_mechval(env, wheel)
        except BaseException:
            shutil.rmtree(env, ignore_errors=True)
            raise
        _write_record(env, wanted)
        return env


def _pinned_env(envs: Path, release: Release) -> Path:
    """ENVS/.pins-<hash>-py<X.Y>: a venv with the pins alone (no engine,
    no mechval), created once; the seed of every release's environment."""
    wanted = {"requirements": list(release.requirements), "python": sys.version.split()[0]}
    key = hashlib.sha256(json.dumps(wanted).encode()).hexdigest()[:12]
    name = f".pins-{key}-py{sys.version_info.major}.{sys.version_info.minor}"
    env = envs / name
    with _locked(envs, name):
        if _read_record(env) == wanted:
            return env
        shutil.rmtree(env, ignore_errors=True)
        try:
            venv.EnvBuilder(with_pip=False, symlinks=True, clear=True).create(env)
            _pip(_pip_install(env) + list(release.requirements), "install mechval's pinned dependencies")
        except BaseException:
            shutil.rmtree(env, ignore_errors=True)
            raise
        _write_record(env, wanted)
        return env


@contextlib.contextmanager
def _locked(envs: Path, name: str):
    with open(envs / f".{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


def _site_packages(env: Path) -> Path:
    return env / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages"


def _link_tree(source: Path, target: Path) -> None:
    """Copy a folder's files as hard links (a copy where the file system
    has none): pip replaces a file by removing it, never by writing into
    it, so an environment's changes do not reach the source."""
    try:
        shutil.copytree(source, target, copy_function=os.link, dirs_exist_ok=True)
    except OSError:
        shutil.rmtree(target, ignore_errors=True)
        shutil.copytree(source, target, dirs_exist_ok=True)


def _pip_install(env: Path) -> list[str]:
    # --no-compile: byte-compiling every module of numpy, pandas, scipy and
    # dask doubles the install time; Python compiles what it imports.
    return [sys.executable, "-m", "pip", "--python", str(python_of(env)), "install", "--quiet", "--no-compile",
            "--disable-pip-version-check"]


def _install_mechval(env: Path, wheel: Path) -> None:
    _pip(_pip_install(env) + ["--no-deps", "--force-reinstall", str(wheel)], "install this mechval")


def _pip(command: list[str], what: str) -> None:
    try:
        done = subprocess.run(command, capture_output=True, text=True, env=clean_environ(), timeout=INSTALL_TIMEOUT)
    except subprocess.TimeoutExpired:
        raise ReleaseUnavailable(f"cannot {what}: pip took over {INSTALL_TIMEOUT:g} s") from None
    if done.returncode != 0:
        raise ReleaseUnavailable(f"cannot {what}: {pip_reason(done.stderr) or f'pip exit status {done.returncode}'}")


def pip_reason(stderr: str) -> str:
    """pip's own error lines, on one line: its warnings and its list of
    releases made for other Pythons left out, each line at most 300
    characters."""
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    errors = [re.sub(r"^ERROR:\s*", "", line) for line in lines
              if line.startswith("ERROR:") and "Ignored the following versions" not in line]
    return " ".join(line[:300] for line in (errors or lines[-2:]))


def _read_record(env: Path) -> dict | None:
    try:
        return json.loads((env / RECORD).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def _write_record(env: Path, record: dict) -> None:
    with tempfile.NamedTemporaryFile("w", dir=env, delete=False, suffix=".tmp") as f:
        json.dump(record, f, indent=2)
    os.replace(f.name, env / RECORD)
