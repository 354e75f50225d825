"""Command line: a thin layer over the library (``fmu-fdi --help``)."""
from __future__ import annotations

import argparse
import sys

from .errors import DesignError, ModelError


def _analyze(args) -> int:
    from .analysis import detectability, isolability
    from .model import FDIModel

    model = FDIModel.from_file(args.model)
    det = detectability(model)
    iso = isolability(model)
    print(f"model '{model.name}': n={model.n}, u={model.u_names}, y={model.y_names}, d={model.d_names}, "
          f"w={model.w_names}, {'dt=' + format(model.dt, 'g') if model.dt else 'continuous'}")
    width = max([len("fault")] + [len(n) for n in model.fault_names])
    print(f"{'fault':<{width}}  kind        detectable  rank[Gd Gf]  rank Gd  isolable from")
    for j, spec in enumerate(model.faults):
        d = det[spec.name]
        others = [model.fault_names[k] for k in range(len(model.faults)) if k != j and iso["matrix"][j, k]]
        print(f"{spec.name:<{width}}  {spec.kind:<10}  {'yes' if d['detectable'] else 'NO':<10}  "
              f"{d['rank_Gd_Gf']:<11}  {d['rank_Gd']:<7}  {', '.join(others) or '-'}")
    print(f"fully isolable (structure I achievable): {'yes' if iso['fully_isolable'] else 'no'}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="fmu-fdi", description=__doc__)
    sub = p.add_subparsers(dest="command", required=True)
    a = sub.add_parser("analyze", help="detectability / isolability table of a model file")
    a.add_argument("model", help="model file (.toml or .json)")
    a.set_defaults(func=_analyze)
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ModelError, DesignError) as exc:
        print(f"fmu-fdi: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
