"""``python -m plant_fmus build [--native] [--out DIR]`` / ``python -m plant_fmus models``."""
from __future__ import annotations

import argparse
import sys

from . import PLANTS, build, build_all, write_model_files


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m plant_fmus", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    b = sub.add_parser("build", help="build plant FMUs")
    b.add_argument("names", nargs="*", help=f"plants to build (default all: {', '.join(PLANTS)})")
    b.add_argument("--out", default="out", help="output folder (default: out)")
    b.add_argument("--native", action="store_true",
                   help="build the native C FMUs <name>_native.fmu instead (docs/native-plants.md)")
    b.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version of a --native build (default 2)")
    sub.add_parser("models", help="recompute and rewrite the model files from the plant parameters")
    args = parser.parse_args(argv)
    if args.command == "models":
        for path in write_model_files():
            print(path)
        return 0
    if args.native:
        from fmu_fdi.native.build import NativeBuildError

        from .native_build import build_native_all

        try:
            paths = build_native_all(args.out, args.names, args.fmi)
        except (KeyError, NativeBuildError) as exc:
            print(f"error: {exc.args[0] if isinstance(exc, KeyError) else exc}", file=sys.stderr)
            return 2
    else:
        paths = [build(n, args.out) for n in args.names] if args.names else build_all(args.out)
    for path in paths:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
