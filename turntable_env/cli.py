"""Command line: ``turntable <subcommand>``.

Subcommands:
    params   print a parameter set (Table D.1 ``real`` or D.2 ``thesis``), given and derived
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from .params import get_parameter_set

__all__ = ["main"]


def _fmt(value: object) -> str:
    if isinstance(value, bool) or isinstance(value, str):
        return str(value)
    if isinstance(value, list):
        return "[" + ", ".join(f"{v:.4g}" for v in value) + "]"
    return f"{value:.4g}"


def _cmd_params(args: argparse.Namespace) -> int:
    ps = get_parameter_set(args.set)
    if args.json:
        print(ps.to_json())
        return 0
    print(f"parameter set '{ps.name}'")
    rows = ps.describe()
    w = max(len(q.name) for q in rows)
    for q in rows:
        print(f"  {q.name:<{w}}  {_fmt(q.value):>40} {q.unit:<9} {q.kind:<8} {q.source}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="turntable", description="piezo stick-slip turntable tools")
    sub = p.add_subparsers(dest="command", required=True)
    pp = sub.add_parser("params", help="print a parameter set with every given and derived value")
    pp.add_argument(
        "--set",
        choices=["real", "thesis"],
        default="real",
        help="Table D.1 (real) or Table D.2 (thesis)",
    )
    pp.add_argument("--json", action="store_true", help="print JSON")
    pp.set_defaults(func=_cmd_params)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except ValueError as exc:
        print(f"turntable: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
