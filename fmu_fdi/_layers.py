"""The layers of the package, ground first: a module imports only from its own layer or the
ones below it (at module level or inside a function), and no imports run in a circle
(tests/test_layers.py checks both; README.md, "Layers", shows this table).

Each entry names modules or packages relative to ``fmu_fdi`` (``"design"`` is every module of
``fmu_fdi/design/`` the more specific entries leave over; ``"__init__"`` is the package face).
The order follows the theory (Varga 2017; docs/ARCHITECTURE "layers you can see"): the model
is data plus its own algebra; a residual generator Q acts on it and has the internal form
R = Q·Ge; the one judge measures R; the state-space toolkit and analysis answer to the judge;
synthesis stands on all of these; diagnosis, export and the tools around them come after.
"""
from __future__ import annotations

#: (name, what it holds, modules), lowest layer first
LAYERS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    ("numerics", "numbers, files, and the numpy-only per-sample runtime",
     ("errors", "linalg", "compression", "freqresp", "lti", "margin", "progress", "outpath", "_schema", "sidecar",
      "inputfiles", "runtime", "_layers")),
    ("model", "the FDI model: data and its own algebra; model sets",
     ("faults", "model", "modelset")),
    ("generator", "the residual generator Q and its internal form R = Q Ge",
     ("generator",)),
    ("judge", "post-conditions on the normalised internal form",
     ("design.toolkit.postconditions", "design.toolkit.plant_modes")),
    ("toolkit", "design/toolkit/: minimal bases, pencils, stable factors, co-outer",
     ("design.toolkit",)),
    ("analysis", "structure, gains, gaps, leakage; robustness",
     ("analysis", "robustness")),
    ("synthesis", "design/problems/: one module per problem; design/observers/ beside",
     ("design.problems", "design.observers", "design")),
    ("diagnosis", "evaluation, design files, diagnoser, scheduling",
     ("designfile", "evaluation", "diagnoser", "schedule", "designinfo")),
    ("export", "native C target; the pythonfmu builder picks the target",
     ("native", "fmu")),
    ("around", "co-simulation, identification, campaigns, results",
     ("cosim", "metrics", "recorded", "identify", "campaign", "report")),
    ("faces", "command line, demo, pytest helpers, the package face",
     ("cli", "demo", "testing", "__main__", "__init__")),
)


def layer_of(module: str, layers=LAYERS, package: str = "fmu_fdi") -> str | None:
    """The layer of ``module`` (``"fmu_fdi.design.problems.nullspace"`` or
    ``"design.problems.nullspace"``): the one whose most specific entry is the module or one
    of its packages; None when unlisted."""
    rel = module[len(package) + 1:] if module.startswith(package + ".") else module
    rel = "__init__" if rel == package else rel
    best, found = -1, None
    for name, _, entries in layers:
        for e in entries:
            if (rel == e or rel.startswith(e + ".")) and len(e) > best:
                best, found = len(e), name
    return found


def table() -> str:
    """The layer list as README.md shows it, ground at the bottom (a fenced block's lines)."""
    width = max(len(n) for n, _, _ in LAYERS)
    lines = [f"{k:2d} {name:<{width}}  {what}\n{'':{width + 5}}{', '.join(entries)}"
             for k, (name, what, entries) in enumerate(LAYERS, 1)]
    return "\n".join(reversed(lines))
