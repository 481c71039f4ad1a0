"""The README's headline table is what hdmaint.headline renders from
docs/results/*.json (the files the measuring tools write), and each
rendered number is the one in those files."""
from __future__ import annotations

import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

from hdmaint import headline


def test_readme_headline_is_current():
    text = headline.README.read_text()
    assert headline.BEGIN in text and headline.END in text
    now = headline.splice(text, headline.render(headline.load()))
    assert now == text, ("README.md headline is stale: run `cd tools && ../.venv/bin/python "
                         "-m hdmaint.headline --write`")


def test_two_commands_in_the_first_twenty_lines():
    head = headline.README.read_text().splitlines()[:20]
    assert any(line.startswith("tools/demo") for line in head)
    assert any(line.startswith("tools/test") for line in head)
    assert "exec tools/test" in (ROOT / ".ci" / "run").read_text()


def test_readme_is_a_front_door():
    assert len(headline.README.read_text().splitlines()) <= 300


def test_numbers_come_from_the_result_files():
    """The demo row quotes the demo's own numbers (read here from the JSON
    independently of the renderer) and the corpus row its counts."""
    results = headline.load()
    block = headline.render(results)
    demo = json.loads((headline.RESULTS / "demo.json").read_text())
    assert f"**{demo['operate_with_profile']['rms_error_filtered_nm']} N m**" in block
    corpus = json.loads((headline.RESULTS / "corpus.json").read_text())
    assert re.search(rf"\| {corpus['cases']} cases", block)
    assert sum(corpus["per_class"].values()) == corpus["cases"]
    # the random-joint row: its worse-than-raw count summed here from the runs
    rnd = json.loads((headline.RESULTS / "random.json").read_text())
    runs = [v for part in ("declared", "undeclared") for x in rnd[part]["runs"]
            for v in x["paths"].values()]
    worse = sum(v["worse_than_raw"] for v in runs)
    assert f"filtered worse than raw in **{worse} of {len(runs)}** runs" in block


def test_missing_result_file_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(headline, "RESULTS", tmp_path)
    rc = headline.main(["--check"])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "demo.json" in err


def _stale_readme(tmp_path, monkeypatch):
    """A copy of the README with an emptied headline block, as headline.README."""
    text = headline.README.read_text()
    pre, rest = text.split(headline.BEGIN, 1)
    stale = pre + headline.BEGIN + "\n" + headline.END + rest.split(headline.END, 1)[1]
    readme = tmp_path / "README.md"
    readme.write_text(stale)
    monkeypatch.setattr(headline, "README", readme)
    return readme, stale, text


def test_write_replaces_the_block(tmp_path, monkeypatch):
    readme, stale, current = _stale_readme(tmp_path, monkeypatch)
    assert headline.main(["--check"]) == 1
    assert headline.main(["--write"]) == 0
    assert readme.read_text() == current != stale      # the README is current (test above)
    assert headline.main(["--check"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["README.md"]


def test_failed_write_is_one_line_and_leaves_nothing(tmp_path, capsys, monkeypatch):
    import errno
    import os
    readme, stale, _ = _stale_readme(tmp_path, monkeypatch)

    def replace_fails(src, dst):
        raise OSError(errno.EIO, "Input/output error", str(dst))
    monkeypatch.setattr(os, "replace", replace_fails)
    rc = headline.main(["--write"])
    err = capsys.readouterr().err
    assert rc == 3 and len(err.strip().splitlines()) == 1 and "README.md" in err
    assert readme.read_text() == stale
    assert sorted(p.name for p in tmp_path.iterdir()) == ["README.md"]   # no temporary left
