"""The commands a newcomer copies first do what the page around them says.

README.md's Quickstart command (the built-in example) and the design-and-run walk of
docs/getting-started.md are read from the pages themselves, run in a scratch folder and held to
the prose: the files the README says the command writes, the sensor names it gives that table,
and the output getting started quotes for ``cfdesign run --reference`` (its figures included).
test_docs_site.py holds the pages' option names to the parser; this holds their results.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import numpy as np
from conftest import run_cli

ROOT = Path(__file__).resolve().parents[1]
NUMBER = r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?"


def _section(page: Path, heading: str) -> str:
    """The text of ``page`` from the line ``heading`` to the next heading of its level."""
    text = page.read_text()
    level = heading.split()[0]
    start = text.index(f"\n{heading}\n") + len(heading) + 2
    end = re.search(rf"^{level} ", text[start:], re.M)
    return text[start:start + end.start()] if end else text[start:]


def _cfdesign_words(line: str) -> list:
    """The arguments of the ``cfdesign`` command of a shell line (after any ``&&``)."""
    command = line.split("&&")[-1].split("#")[0].strip().removeprefix("$ ")
    words = shlex.split(command)
    assert words[0] == "cfdesign", line
    return words[1:]


def test_the_quickstart_command_writes_the_files_the_readme_names(tmp_path, monkeypatch):
    """``cfdesign design -o dckf3_gains.json --bode dckf3_bode.png``: the gain table and the
    Bode plot the paragraph below names, a complementary and stable table whose sensors are those
    the README gives the Quickstart's table (in 'Running a designed filter')."""
    readme = ROOT / "README.md"
    quickstart = _section(readme, "## Quickstart")
    first = re.search(r"^```\n(.*?)\n", quickstart, re.M).group(1)
    words = _cfdesign_words(first)
    prose = quickstart.split("```")[-1]
    named = re.findall(r"`([\w.-]+\.(?:json|png))`", prose)
    assert named and set(named) <= set(words), (named, words)

    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(*words)
    assert code == 0, err
    for name in named:
        assert (tmp_path / name).stat().st_size > 500, name
        assert f"wrote {name}" in out

    import cfdesign

    table = cfdesign.load_gains(tmp_path / next(n for n in named if n.endswith(".json")))
    assert table.checks["complementary"] and table.checks["stable"]
    said = re.search(r"Quickstart's robot-heading table calls its\s+sensors ([^;]*);",
                     _section(readme, "## Running a designed filter")).group(1)
    assert [s.name for s in table.sensors] == re.findall(r"`(\w+)`", said)


def test_the_getting_started_walk_prints_what_the_page_quotes(tmp_path, monkeypatch):
    """Steps 1, 2 and 4 of getting started as written (save ``heading.toml``, design it, draw the
    log with the page's Python, run it with ``--reference``): the output is the page's quote, its
    text exactly and its figures to the digits quoted."""
    page = (ROOT / "docs" / "getting-started.md").read_text()
    monkeypatch.chdir(tmp_path)
    (tmp_path / "heading.toml").write_text(re.search(r"^```toml\n(.*?)^```", page, re.M | re.S).group(1))
    consoles = re.findall(r"^```console\n(.*?)^```", page, re.M | re.S)
    design = next(c for c in consoles if c.startswith("$ cfdesign design "))
    code, _, err = run_cli(*_cfdesign_words(design.splitlines()[0]))
    assert code == 0, err

    draw = next(b for b in re.findall(r"^```python\n(.*?)^```", page, re.M | re.S) if "model_log" in b)
    exec(compile(draw, "getting-started.md", "exec"), {})

    run = next(c for c in consoles if c.startswith("$ cfdesign run "))
    command, *quoted = run.strip().splitlines()
    code, out, err = run_cli(*_cfdesign_words(command))
    assert code == 0, err
    printed = out.strip().splitlines()
    assert [re.sub(NUMBER, "#", q) for q in quoted] == [re.sub(NUMBER, "#", p) for p in printed], out
    for q, p in zip(quoted, printed, strict=True):
        # figures as the page rounds them (6 significant digits): a changed design or log fails
        np.testing.assert_allclose([float(x) for x in re.findall(NUMBER, p)],
                                   [float(x) for x in re.findall(NUMBER, q)], rtol=5e-6, err_msg=p)

