"""The `mechval` command line (DESIGN.md: stable; scripts outside call it)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .scenario import ScenarioError


class UsageError(Exception):
    """A user error reported as one line, exit status 2."""


def _load(name: str):
    from mechval.scenarios import load
    return load(name)


def cmd_list(args) -> int:
    from mechval.engines.registry import availability
    from mechval.scenarios import builtin_names
    print("scenarios:")
    for name in builtin_names():
        s = _load(name)
        tags = f" [{', '.join(s.tags)}]" if s.tags else ""
        print(f"  {name:<28} {s.mechanism:<13}{tags} {s.description}")
    print("engines:")
    print(f"  {'reference':<12} available (analytic)")
    for engine, reason in availability().items():
        print(f"  {engine:<12} {'available' if not reason else 'unavailable: ' + reason}")
    return 0


def simulate(scenario, engine: str):
    """Canonical signals of `engine` ('reference' or an adapter name)."""
    if engine == "reference":
        from .reference import simulate_reference
        return simulate_reference(scenario)
    from mechval.engines.registry import adapter
    return adapter(engine).simulate(scenario)


def cmd_simulate(args) -> int:
    scenario = _load(args.scenario)
    signals = simulate(scenario, args.engine)
    signals.to_csv(args.csv)
    for name, reason in signals.missing.items():
        print(f"note: {name}: missing values ({reason})", file=sys.stderr)
    print(f"wrote {args.csv}: {len(signals.frame)} samples × {signals.frame.shape[1]} columns "
          f"({args.engine} {signals.version})")
    return 0


def cmd_analyse(args) -> int:
    from .analysis import analyse, format_analysis
    print(format_analysis(analyse(_load(args.scenario))))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mechval", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="scenarios and engines found").set_defaults(func=cmd_list)
    p = sub.add_parser("simulate", help="canonical signals at the scenario's samples")
    p.add_argument("scenario", help="built-in scenario name or path to a .toml file")
    p.add_argument("--engine", default="reference", help="reference|mujoco|pybullet|exudyn")
    p.add_argument("--csv", required=True, type=Path, help="output CSV file")
    p.set_defaults(func=cmd_simulate)
    p = sub.add_parser("analyse", help="engineering analysis: Grashof, transmission angle, toggles")
    p.add_argument("scenario")
    p.set_defaults(func=cmd_analyse)
    return parser


def main(argv: list[str] | None = None) -> int:
    from mechval.engines.registry import EngineUnavailable, UnknownEngine
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ScenarioError, UnknownEngine, UsageError) as exc:
        print(f"mechval: error: {exc}", file=sys.stderr)
        return 2
    except EngineUnavailable as exc:
        print(f"mechval: engine unavailable: {exc}", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        print("mechval: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
