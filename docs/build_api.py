"""Build the API reference of fmu_fdi (HTML, from the numpydoc docstrings) with pdoc.

    python docs/build_api.py [OUT_DIR]        default OUT_DIR: docs/api

Every public module of the package gets a page; ``index.html`` links them. The build is
part of the tests (``tests/test_docs.py``), so CI fails when a docstring breaks it. pdoc
renders numpydoc sections and LaTeX-free math as written; no network is used (pdoc's
search index and assets are bundled).
"""
from __future__ import annotations

import sys
import warnings
from pathlib import Path

#: modules that are scripts or templates run elsewhere (inside an FMU or a host process),
#: documented by their module docstring in the source rather than as API
EXCLUDED = ("fmu_fdi.fmu.host_worker", "fmu_fdi.fmu.slave_template")


def public_modules() -> list[str]:
    """``fmu_fdi`` and every submodule whose name has no leading underscore, less
    :data:`EXCLUDED` (the package's ``__all__`` lists names, not modules, so pdoc would
    otherwise skip the submodules)."""
    import pkgutil

    import fmu_fdi

    names = ["fmu_fdi"]
    for info in pkgutil.walk_packages(fmu_fdi.__path__, "fmu_fdi."):
        parts = info.name.split(".")
        if not any(p.startswith("_") for p in parts) and info.name not in EXCLUDED:
            names.append(info.name)
    return names


def build(out_dir="docs/api") -> list[Path]:
    """Write the HTML reference into ``out_dir``; return the pages written.

    Raises
    ------
    RuntimeError
        pdoc warned about a docstring or a module it could not import (the messages).
    """
    import pdoc
    import pdoc.render

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    pdoc.render.configure(docformat="numpy", show_source=False, footer_text="fmu-fdi API reference",
                          search=True)
    modules = public_modules()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pdoc.pdoc(*modules, output_directory=out)
    # a package without __all__ brings its submodules itself: listing them again is harmless
    problems = [str(w.message) for w in caught
                if ("pdoc" in (w.filename or "") or issubclass(w.category, RuntimeWarning))
                and "has already been added" not in str(w.message)]
    if problems:
        raise RuntimeError("pdoc: " + " | ".join(problems))
    return sorted(out.rglob("*.html"))


if __name__ == "__main__":
    pages = build(sys.argv[1] if len(sys.argv) > 1 else "docs/api")
    print(f"{len(pages)} pages written to {pages[0].parent if pages else '-'}")
