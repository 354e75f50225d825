"""The longest functions of the package (issue 20, "split the long functions along their stages").

A function's length is its lines from the ``def`` (decorators excluded) to its last line, docstring
and comments included, as ``ast`` reports them (``end_lineno - lineno + 1``); the second column
leaves its docstring out. Nested functions are counted inside their parent and also listed on their
own, by qualified name. Sorted by the first column.

    python benchmarks/longest_functions.py [--top 10] [--over 120] [PACKAGE_DIR]

``--over N`` also prints how many functions are longer than N lines.
"""
from __future__ import annotations

import argparse
import ast
from pathlib import Path


def functions(root: Path):
    """``(lines, lines without the docstring, "module:qualified.name")`` of every function and method
    under ``root``."""
    out = []
    for path in sorted(root.rglob("*.py")):
        module = ".".join(path.relative_to(root.parent).with_suffix("").parts)
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))

        def visit(node, prefix):
            for child in ast.iter_child_nodes(node):
                if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    name = f"{prefix}{child.name}"
                    lines = child.end_lineno - child.lineno + 1
                    first = child.body[0]
                    doc = (first.end_lineno - first.lineno + 1 if isinstance(first, ast.Expr)
                           and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str) else 0)
                    out.append((lines, lines - doc, f"{module}:{name}"))
                    visit(child, name + ".")
                elif isinstance(child, ast.ClassDef):
                    visit(child, f"{prefix}{child.name}.")

        visit(tree, "")
    return sorted(out, reverse=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default=str(Path(__file__).resolve().parent.parent / "fmu_fdi"))
    ap.add_argument("--top", type=int, default=10)
    ap.add_argument("--over", type=int, default=120)
    args = ap.parse_args()
    found = functions(Path(args.root))
    print("lines  without docstring  function")
    for lines, code, name in found[:args.top]:
        print(f"{lines:5d}  {code:17d}  {name}")
    print(f"{sum(1 for n, _, _ in found if n > args.over)} of {len(found)} functions are longer than {args.over} lines "
          f"({sum(1 for _, c, _ in found if c > args.over)} without their docstrings)")


if __name__ == "__main__":
    main()
