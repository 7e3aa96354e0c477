"""The documentation in docs/ cannot rot: its scenario examples load, its
tables of signals, tolerances and engine settings match the code, its links
resolve, and nothing in the repository points to files outside it."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest

from conftest import engine_or_skip
from mechval.engines.registry import ENGINE_NAMES
from mechval.linkages import LINKAGES, build_mechanism
from mechval.reference import simulate_reference
from mechval.scenario import DEFAULT_TOLERANCE
from mechval.scenarios import load, parse
from mechval.signals import SIGNAL_CLASS, signal_names

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
    reference = simulate_reference(scenario)
    assert list(reference.frame.columns) == list(signal_names(scenario.mechanism))


@pytest.mark.engine
@pytest.mark.parametrize("engine_name", ENGINE_NAMES)
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


ENGINE_TITLES = {"mujoco": "MuJoCo", "pybullet": "PyBullet", "exudyn": "Exudyn"}


@pytest.mark.engine
@pytest.mark.parametrize("engine_name", ENGINE_NAMES)
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
