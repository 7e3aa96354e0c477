"""The documentation in docs/ cannot rot: its scenario examples load, its
tables of signals, tolerances and engine settings match the code, every
command is listed, the layers it states hold in the imports, its plug-in
example installs and passes the adapter contract, its links resolve, and
nothing in the repository points to files outside it."""

from __future__ import annotations

import argparse
import ast
import importlib
import os
import re
import subprocess
import sys
import sysconfig
import tomllib
from pathlib import Path

import pytest

from conftest import ENGINES, engine_or_skip
from mechval.harness.cli import build_parser
from mechval.reference.linkages import LINKAGES, build_mechanism
from mechval.harness.simulate import simulate
from mechval.model.scenario import DEFAULT_TOLERANCE
from mechval.scenarios import load, parse
from mechval.records.signals import SIGNAL_CLASS, signal_names

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(DOCS.glob("*.md")) + [ROOT / "README.md"]
#: A fenced block whose info string is "toml scenario" is a complete scenario file.
FENCE = re.compile(r"^```(\w*)([^\n]*)\n(.*?)^```", re.S | re.M)


def blocks(language: str, marker: str | None = None) -> list:
    """pytest params (text, id) of the fenced blocks in the docs with this
    language (and marker word in the info string, if given)."""
    found = []
    for page in PAGES:
        for k, match in enumerate(FENCE.finditer(page.read_text(encoding="utf-8"))):
            lang, info, text = match.groups()
            if lang == language and (marker is None or marker in info.split()):
                found.append(pytest.param(text, id=f"{page.relative_to(ROOT)}#{k}"))
    return found


def section(page: str, title: str) -> str:
    """The text of the `## title` section of a docs page (to the next `## `)."""
    text = (DOCS / page).read_text(encoding="utf-8")
    parts = re.split(r"^## ", text, flags=re.M)
    matches = [p for p in parts if p.split("\n", 1)[0].strip().lower() == title.lower()]
    assert len(matches) == 1, f"{page}: no single section '## {title}'"
    return matches[0]


def table_rows(text: str) -> list[list[str]]:
    """Cells of every Markdown table row in `text` (header and rule rows too)."""
    return [[c.strip() for c in line.strip().strip("|").split("|")]
            for line in text.splitlines() if line.lstrip().startswith("|")]


def test_docs_have_scenario_examples():
    assert len(blocks("toml", "scenario")) >= len(LINKAGES)


@pytest.mark.parametrize("text", blocks("toml"))
def test_toml_blocks_are_valid_toml(text):
    tomllib.loads(text)


@pytest.mark.parametrize("text", blocks("toml", "scenario"))
def test_scenario_examples_load_and_have_a_reference(text):
    scenario = parse(tomllib.loads(text), "docs example")
    reference = simulate(scenario, "reference")
    assert list(reference.frame.columns) == list(signal_names(scenario.mechanism))


@pytest.mark.engine
@pytest.mark.parametrize("engine_name", ENGINES)
def test_scenario_examples_engine_settings_are_accepted(engine_name):
    engine = engine_or_skip(engine_name)
    for param in blocks("toml", "scenario"):
        scenario = parse(tomllib.loads(param.values[0]), "docs example")
        engine.settings_for(scenario, build_mechanism(scenario))     # raises on a bad key or value


def test_every_kind_has_an_example():
    kinds = {tomllib.loads(p.values[0])["mechanism"] for p in blocks("toml", "scenario")}
    assert kinds == set(LINKAGES)


def test_signal_table_matches_the_code():
    """conventions.md lists every canonical signal with its mechanisms and class."""
    rows = [r for r in table_rows(section("conventions.md", "Signals")) if r[0].startswith("`")]
    documented = {}
    for name, kinds, cls, *_ in rows:
        kinds = set(LINKAGES) if kinds == "all" else set(re.findall(r"`(\w+)`", kinds))
        documented[name.strip("`")] = (kinds, cls)
    for kind in LINKAGES:
        listed = {name for name, (kinds, _) in documented.items() if kind in kinds}
        assert listed == set(signal_names(kind)) - {"t"}, kind
    for name, (_, cls) in documented.items():
        assert cls == SIGNAL_CLASS[name], name


def test_tolerance_table_matches_the_defaults():
    rows = [r for r in table_rows(section("scenario-format.md", "`[tolerance]`")) if r[0].startswith("`")]
    assert {r[0].strip("`"): float(r[1]) for r in rows} == DEFAULT_TOLERANCE


ENGINE_TITLES = {"mujoco": "MuJoCo", "pybullet": "PyBullet", "exudyn": "Exudyn", "pinocchio": "Pinocchio",
                 "opensim": "OpenSim", "drake": "Drake"}


@pytest.mark.engine
@pytest.mark.parametrize("engine_name", ENGINES)
def test_every_engine_setting_is_documented(engine_name):
    """engines.md has a settings row per key, and the summary in
    scenario-format.md lists exactly the adapter's keys."""
    engine = engine_or_skip(engine_name)
    scenario = load("fourbar-seed")
    keys = set(engine.default_settings(build_mechanism(scenario), scenario.time.t))
    settings_rows = {r[0].strip("`") for r in table_rows(section("engines.md", ENGINE_TITLES[engine_name]))}
    assert keys <= settings_rows, keys - settings_rows
    summary = {r[0].strip("`"): r[1] for r in table_rows(section("scenario-format.md", "`[engines.NAME]`"))}
    assert set(re.findall(r"`(\w+)`", summary[f"`{engine_name}`".strip("`")])) == keys


def subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The parser's sub-commands by name."""
    actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(actions[0].choices) if actions else {}


def test_every_command_is_listed_in_the_docs_index():
    """docs/README.md lists every `mechval` command (and every action of a
    command that has them, e.g. `baseline save|check`)."""
    text = (DOCS / "README.md").read_text(encoding="utf-8")
    for name, command in subcommands(build_parser()).items():
        assert f"mechval {name}" in text, name
        for action in subcommands(command):
            assert re.search(rf"mechval {name} \S*\b{action}\b", text), f"{name} {action}"


#: Folder → the package it is installed as.
LAYER_PACKAGES = {"core": "mechval", "scenarios": "mechval.scenarios", "engines": "mechval.engines",
                  "reports": "mechval.reports", "harness": "mechval.harness", "testing": "mechval.testing"}


def layer_of(module: str) -> str | None:
    """The folder (layer) of an imported mechval module, None if not mechval."""
    for folder, package in LAYER_PACKAGES.items():
        if folder != "core" and (module == package or module.startswith(package + ".")):
            return folder
    return "core" if module == "mechval" or module.startswith("mechval.") else None


def imported_layers(folder: str) -> dict[str, set[str]]:
    """Layer → the files of `folder` that import from it (function-local
    imports included; relative imports stay inside the folder's package)."""
    found: dict[str, set[str]] = {}
    for path in sorted((ROOT / folder).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
            for name in names:
                layer = layer_of(name)
                if layer and layer != folder:
                    found.setdefault(layer, set()).add(str(path.relative_to(ROOT / folder)))
    return found


def test_the_layers_hold_in_the_imports():
    """Each folder imports only the layers docs/README.md's "Layers" table
    allows it ("nothing of the others", named layers, or "all of the
    above": the rows above its own)."""
    rows = [r for r in table_rows(section("README.md", "Layers")) if r[0].startswith("`") and r[0].endswith("/`")]
    allowed = {}
    for folder, _package, _holds, may in rows:
        folder = folder.strip("`/")
        allowed[folder] = set(allowed) if "all" in may else set(re.findall(r"`(\w+)`", may))
    assert set(allowed) == set(LAYER_PACKAGES)
    for folder, may in allowed.items():
        wrong = {layer: files for layer, files in imported_layers(folder).items() if layer not in may}
        assert not wrong, f"{folder}/ imports {wrong}"


def type_hint_only(tree: ast.Module) -> set[int]:
    """ids of the import nodes under `if TYPE_CHECKING:` (type hints only)."""
    return {id(node) for block in ast.walk(tree) if isinstance(block, ast.If)
            and isinstance(block.test, ast.Name) and block.test.id == "TYPE_CHECKING"
            for node in ast.walk(block)}


def test_core_subpackages_hold_in_the_imports():
    """Inside core/, each subpackage (or the contract's modules) imports only
    what docs/README.md's second "Layers" table allows it."""
    rows = [r for r in table_rows(section("README.md", "Layers")) if r[0].startswith("`mechval.")]
    row_of, allowed = {}, {}
    for packages, _holds, may in rows:
        names = [name.split(".")[1] for name in re.findall(r"`(mechval\.\w+)`", packages)]
        for name in names:
            row_of[name] = names[0]
        allowed[names[0]] = set(re.findall(r"`(\w+)`", may))
    core = ROOT / "core"
    assert set(row_of) == {p.stem if p.is_file() else p.name for p in core.iterdir()
                           if (p.suffix == ".py" and p.stem != "__init__") or (p / "__init__.py").exists()}
    wrong = []
    for path in sorted(core.rglob("*.py")):
        part = path.relative_to(core).parts[0].removesuffix(".py")
        if part == "__init__":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        hints = type_hint_only(tree)
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and id(node) not in hints:
                target = (node.module or "").split(".")
                other = row_of.get(target[1]) if target[0] == "mechval" and len(target) > 1 else None
                if other and other != row_of[part] and other not in allowed[row_of[part]]:
                    wrong.append(f"{path.relative_to(core)} imports {node.module}")
    assert not wrong, wrong


def scratch_environment(root: Path) -> Path:
    """A virtual environment of its own under `root` (not mechval's .venv)
    in which mechval is installed: this interpreter's site-packages (mechval
    and its pinned dependencies) added as a site directory, as a
    `pip install PATH/TO/mechval` would have put them there, offline and in
    a second. Returns its python."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(root)], check=True, capture_output=True)
    python = root / "bin" / "python"
    site = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          check=True, capture_output=True, text=True).stdout.strip()
    mechval_site = sysconfig.get_paths()["purelib"]
    Path(site, "mechval-installed.pth").write_text(f"import site; site.addsitedir({mechval_site!r})\n")
    return python


def test_the_plugin_example_installs_and_passes_the_contract(tmp_path):
    """adapters.md's plug-in (module, pyproject.toml with its pinned engine
    library, and test file), laid out as its own repository outside
    mechval's tree and pip-installed into a scratch environment (not
    mechval's .venv), is found through its entry point and passes the
    contract suite from its own test file against the installed mechval:
    no unknown-mark warning, and the only skips are the ones that file
    states."""
    (module,) = [param.values[0] for param in blocks("python", "plugin")]
    (pyproject,) = [param.values[0] for param in blocks("toml", "plugin")]
    (contract_test,) = [param.values[0] for param in blocks("python", "plugin-test")]
    project = tomllib.loads(pyproject)["project"]
    (target,) = project["entry-points"]["mechval.engines"].values()
    package = target.partition(":")[0]
    repository = tmp_path / "mechval-faithful"
    (repository / package).mkdir(parents=True)
    (repository / package / "__init__.py").write_text(module)
    (repository / "pyproject.toml").write_text(pyproject)
    (repository / "tests").mkdir()
    (repository / "tests" / "test_faithful.py").write_text(contract_test)
    python = scratch_environment(tmp_path / "env")
    # Offline: the pinned library is found installed, setuptools builds.
    install = subprocess.run([str(python), "-m", "pip", "install", "--quiet", "--no-index", "--no-build-isolation",
                              str(repository)], capture_output=True, text=True, timeout=120)
    assert install.returncode == 0, install.stdout + install.stderr
    installed = subprocess.run([str(python), "-c", f"import {package}; print({package}.__file__)"],
                               capture_output=True, text=True, cwd=tmp_path, check=True).stdout
    assert Path(installed).is_relative_to(tmp_path / "env"), installed
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    run = subprocess.run([str(python), "-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider", "tests"],
                         cwd=repository, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    assert re.search(r"\d+ passed", run.stdout) and "warning" not in run.stdout.lower(), run.stdout
    stated = re.findall(r'without_\w+ = "([^"]+)"', contract_test)
    skips = [line for line in run.stdout.splitlines() if line.startswith("SKIPPED")]
    assert all(any(line.endswith(reason) for reason in stated) for line in skips), skips


def test_the_plugin_template_pins_its_engine_library():
    """Checklist step 1 in the template itself: its pyproject.toml pins the
    adapter's `library` (numpy here) to the version mechval pins, so that
    both install together."""
    (module,) = [param.values[0] for param in blocks("python", "plugin")]
    (pyproject,) = [param.values[0] for param in blocks("toml", "plugin")]
    (library,) = re.findall(r'library = "(\w+)"', module)
    pins = [d for d in tomllib.loads(pyproject)["project"].get("dependencies", []) if d.startswith(f"{library}==")]
    ours = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    assert len(pins) == 1 and pins[0] in ours, (pins, ours)


def public_api() -> dict[str, list[str]]:
    """adapters.md's "The public API" table: module → names."""
    rows = [r for r in table_rows(section("adapters.md", "The public API")) if r[0].startswith("`")]
    return {module.strip("`"): re.findall(r"`(\w+)`", names) for module, names, _ in rows}


def test_the_public_api_imports():
    """Every name of the public API table imports from its module, and
    mechval.testing exports exactly its listed names."""
    api = public_api()
    assert len(api) >= 15 and all(api.values()), api
    missing = [f"{module}.{name}" for module, names in api.items() for name in names
               if not hasattr(importlib.import_module(module), name)]
    assert not missing, missing
    assert sorted(importlib.import_module("mechval.testing").__all__) == sorted(api["mechval.testing"])


def test_the_docs_examples_use_only_the_public_api():
    """The plug-in, its contract test and the comparison example import
    from mechval nothing that the public API table does not list."""
    api = public_api()
    examples = [p.values[0] for marker in ("plugin", "plugin-test", "compare-example") for p in blocks("python", marker)]
    assert len(examples) == 3
    outside = []
    for text in examples:
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("mechval"):
                outside += [f"{node.module}.{a.name}" for a in node.names if a.name not in api.get(node.module, [])]
            elif isinstance(node, ast.Import):
                outside += [a.name for a in node.names if a.name.startswith("mechval")]
    assert not outside, outside


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_links_resolve():
    """Every relative link in the docs and README names an existing file
    and, for a Markdown page, an existing heading."""
    broken = []
    for page in PAGES:
        for target in re.findall(r"\]\(([^)\s]+)\)", page.read_text(encoding="utf-8")):
            if re.match(r"\w+://", target):
                continue
            path, _, anchor = target.partition("#")
            file = (page.parent / path).resolve() if path else page
            if not file.exists():
                broken.append(f"{page.name}: {target}")
            elif anchor and file.suffix == ".md":
                headings = re.findall(r"^#+ (.+)$", file.read_text(encoding="utf-8"), re.M)
                if anchor not in {slug(h) for h in headings}:
                    broken.append(f"{page.name}: {target}")
    assert not broken, broken


#: Files outside the repository that earlier versions pointed readers to.
OUTSIDE = ("DESIGN" + ".md", "ENGINE" + "_NOTES", "../" + "shared", "/work/" + "shared")
SKIPPED_DIRS = {".venv", ".git", "__pycache__", "baselines", "out", ".pytest_cache", ".hypothesis"}
TEXT_SUFFIXES = {".py", ".md", ".toml", ".j2", ".sh", ".cfg", ".ini", ".txt", ".yaml", ".yml", ""}


def test_nothing_points_outside_the_repository():
    found = []
    for path in ROOT.rglob("*"):
        if (not path.is_file() or SKIPPED_DIRS & set(path.relative_to(ROOT).parts)
                or path.suffix not in TEXT_SUFFIXES or path == Path(__file__).resolve()):
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
            if any(word in line for word in OUTSIDE):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not found, "\n".join(found)
