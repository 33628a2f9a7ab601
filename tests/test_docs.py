"""The user docs stay true: their runnable snippets run, their stats.csv table matches the writer.

Runnable marker: every fenced block opened with ```python in docs/python-api.md and
docs/output-format.md is executed; illustrations that must not run use ```text, ```toml, ```xml.
Blocks of one page run in order in one namespace (a page reads as one session). output-format.md's
snippets read `out/`, so a tiny run is made there first (--no-render, r = 0.04 m, 0.1 s: three
frames at t = 0, 0.04, 0.08, which the snippets name).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from ipsph import cli
from ipsph.io.stats import STATS_COLUMNS

DOCS = Path(__file__).resolve().parents[1] / "docs"
RUNNABLE = re.compile(r"^```python[ \t]*\n(.*?)^```[ \t]*$", re.S | re.M)


def python_blocks(page: str) -> list[str]:
    return RUNNABLE.findall((DOCS / page).read_text(encoding="utf-8"))


def run_blocks(page: str) -> None:
    namespace: dict = {"__name__": f"docs_{page}"}
    for k, block in enumerate(python_blocks(page)):
        code = compile(block, f"{page} python block {k + 1}", "exec")
        exec(code, namespace)  # a failure names the page and the block in the traceback


def test_pages_have_runnable_blocks():
    # guards the marker: if the fence style changed, the tests below would silently run nothing
    assert len(python_blocks("python-api.md")) >= 5
    assert len(python_blocks("output-format.md")) >= 3


def test_python_api_snippets_run(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    run_blocks("python-api.md")


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("docs_run")
    code = cli.main(
        [
            "run",
            "--set",
            "simulation.particle_radius=0.04",
            "--end-time",
            "0.1",
            "--no-render",
            "--quiet",
            "-o",
            str(folder / "out"),
        ]
    )
    assert code == 0
    return folder


@pytest.mark.slow
def test_output_format_snippets_run(tiny_run, monkeypatch, capsys):
    monkeypatch.chdir(tiny_run)
    run_blocks("output-format.md")


def documented_stats_columns() -> list[str]:
    """First-column names of the table in the '## stats.csv' section of output-format.md."""
    text = (DOCS / "output-format.md").read_text(encoding="utf-8")
    section = text.split("\n## stats.csv", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"^\| `([A-Za-z_]+)` \|", section, re.M)


def test_stats_columns_documented_exactly():
    documented = documented_stats_columns()
    assert len(documented) == len(set(documented)), "a stats.csv column is documented twice"
    assert set(documented) == set(STATS_COLUMNS), (
        f"only in the docs: {sorted(set(documented) - set(STATS_COLUMNS))}; "
        f"only in STATS_COLUMNS: {sorted(set(STATS_COLUMNS) - set(documented))}"
    )


def test_stats_columns_in_writer_order():
    # the doc table lists the columns in file order, so it doubles as a reading guide
    assert documented_stats_columns() == list(STATS_COLUMNS)
