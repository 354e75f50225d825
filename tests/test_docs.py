"""The documentation a new user reads says what the code does (issue 11): the API reference
builds from the docstrings, the model-file reference and the method guide cover every key,
fault kind and method, examples in the docs load, and links point at files that exist."""
import json
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parent.parent
DOCS = ROOT / "docs"


def test_api_reference_builds_and_documents_every_public_name(tmp_path):
    pytest.importorskip("pdoc")
    sys.path.insert(0, str(DOCS))
    try:
        import build_api
    finally:
        sys.path.remove(str(DOCS))
    import inspect

    import fmu_fdi

    pages = build_api.build(tmp_path / "api")
    rel = {p.relative_to(tmp_path / "api").as_posix() for p in pages}
    for module in build_api.public_modules():  # one page per public module
        assert module.replace(".", "/") + ".html" in rel, module
    top = (tmp_path / "api" / "fmu_fdi.html").read_text(encoding="utf-8")
    for name in fmu_fdi.__all__:
        assert f'id="{name}"' in top, f"{name} is missing from the API reference"
        assert (inspect.getdoc(getattr(fmu_fdi, name)) or "").strip(), f"{name} has no docstring"


def _blocks(text, lang):
    return re.findall(rf"```{lang}\n(.*?)```", text, re.S)


def test_model_file_reference_covers_every_key_and_its_examples_load(tmp_path):
    from fmu_fdi import FDIModel
    from fmu_fdi import model as model_mod
    from fmu_fdi.faults import KINDS

    text = (DOCS / "model-file.md").read_text(encoding="utf-8")
    for key in sorted(model_mod._TOP_KEYS | model_mod._MATRIX_KEYS) + ["u", "y", "d", "w"]:
        assert f"`{key}`" in text, key
    for kind, keys in {"actuator": ["input"], "sensor": ["output"], "component": ["Bf", "Df"],
                       "parametric": ["dA", "dB", "dC"]}.items():
        row = next(ln for ln in text.splitlines() if ln.startswith(f"| `{kind}` |"))
        assert all(f"`{k}`" in row for k in keys), row
    assert set(KINDS) == {"actuator", "sensor", "component", "parametric"}
    examples = [("toml", b) for b in _blocks(text, "toml") if b.startswith("format")]
    examples += [("json", b) for b in _blocks(text, "json")]
    assert len(examples) == 2
    for lang, body in examples:
        path = tmp_path / f"example.{lang}"
        path.write_text(body, encoding="utf-8")
        model = FDIModel.from_file(path)
        assert model.fault_names
    kinds = {f.kind for f in FDIModel.from_file(tmp_path / "example.toml").faults}
    assert kinds == set(KINDS)  # the complete example shows every kind of fault


def test_method_guide_names_every_cli_method_next_to_its_function():
    from fmu_fdi import design
    from fmu_fdi.cli import METHODS

    text = (DOCS / "methods.md").read_text(encoding="utf-8")
    for name, (fn, _, _) in METHODS.items():
        assert re.search(rf"^\| `{name}` \| `{fn}` \|", text, re.M), name
        assert callable(getattr(design, fn))


def test_doc_links_point_at_files_that_exist():
    sources = [ROOT / "README.md", *DOCS.glob("*.md")]
    missing = []
    for src in sources:
        for ref in re.findall(r"`((?:docs|examples|tests|plant_fmus|fmu_fdi|benchmarks)/[\w./-]+\.\w+)`",
                              src.read_text(encoding="utf-8")):
            if not (ROOT / ref).exists():
                missing.append(f"{src.name}: {ref}")
    assert not missing, missing


def test_readme_keeps_its_first_commands_and_its_python_block_does_not_overwrite_the_cli_fmu():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    first = re.search(r"```\n(.*?)```", text, re.S).group(1).splitlines()
    assert first[0] == 'python3 -m venv .venv && . .venv/bin/activate && pip install ".[test]" && fmu-fdi demo'
    assert first[1] == "python -m pytest -q -n 2"
    cli_outputs = set(re.findall(r"-o (out/[\w.]+)", text))
    python = _blocks(text, "python")[0]
    written = set(re.findall(r'build_fmu\([^,]+, "([^"]+)"\)', python))
    assert written and not written & cli_outputs, (written, cli_outputs)
    assert "inputs=" in python  # the diagnoser gets the plant's inputs in Python too
    sim = next(ln for ln in text.splitlines() if ln.startswith("fmu-fdi simulate"))
    assert "--input examples/dts200_pumps.csv" in sim


def test_license_matches_pyproject():
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    meta = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert meta["license"]["text"] == "MIT"
    assert (ROOT / "LICENSE").read_text(encoding="utf-8").startswith("MIT License")
    assert json.dumps(meta["version"]) and re.fullmatch(r"\d+\.\d+\.\d+", meta["version"])


def _readme_commands() -> list:
    """The README's shell commands, continuation lines joined, in order (the install line of its
    first block excepted: it is the environment the tests run in)."""
    blocks, current = [], None
    for line in (ROOT / "README.md").read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            if current is None:
                current = [] if line.strip() == "```" else False  # False: a block in a language
            else:
                if current is not False:
                    blocks.append("\n".join(current))
                current = None
        elif isinstance(current, list):
            current.append(line)
    out = []
    for block in blocks:
        joined = re.sub(r"\\\n\s*", " ", block)
        for line in joined.splitlines():
            cmd = line.split("  #", 1)[0].strip()
            if cmd.startswith("fmu-fdi "):
                out.append(cmd)
    return out


@pytest.mark.slow
def test_readme_commands_run_as_written(tmp_path):
    """Every `fmu-fdi ...` line of the README's command blocks runs, in order, in a fresh folder
    holding the repository's examples/ and plant_fmus/, and exits 0; the worked example prints
    what the README says it prints."""
    import shlex
    import subprocess

    for name in ("examples", "plant_fmus"):
        (tmp_path / name).symlink_to(ROOT / name)
    commands = _readme_commands()
    assert any(c.startswith("fmu-fdi campaign --example") for c in commands)
    outputs = {}
    for cmd in commands:
        if cmd.startswith("fmu-fdi --") or cmd.startswith("fmu-fdi demo"):
            continue  # --version/--help; the demo has its own test
        r = subprocess.run([sys.executable, "-m", "fmu_fdi", *shlex.split(cmd)[1:]], cwd=tmp_path,
                           capture_output=True, text=True, timeout=900)
        assert r.returncode == 0, (cmd, r.stderr[-2000:])
        outputs[cmd] = r.stdout
    plot = next(o for c, o in outputs.items() if c.startswith("fmu-fdi plot out/run.csv"))
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    claim = re.search(r"The last command prints `([^`]*)`", text).group(1)
    assert claim in plot, (claim, plot)
