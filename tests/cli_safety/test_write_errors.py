"""Writing that fails says so in one line naming the path and the fix, never a traceback: a missing folder, a
folder given as the output file, a full disk (a real full tmpfs; /dev/full as standard output: exit 74, the
partial file removed), a reader that went away (exit 141, quietly)."""

from __future__ import annotations

import subprocess
import sys

from posed.cli import main
from tests.cli_safety.conftest import posed


def _one_line(err: str) -> str:
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if not ln.startswith("posed history: reading ")]
    assert len(lines) == 1, err
    return lines[0]


def test_history_csv_into_a_missing_folder_or_a_folder(history_db, tmp_path, capsys):
    out = tmp_path / "nodir" / "x.csv"
    assert main(["history", "--db", str(history_db), "--csv", "-o", str(out)]) == 2
    line = _one_line(capsys.readouterr().err)
    assert f"cannot write {out}: the folder {out.parent} does not exist" in line
    empty = tmp_path / "emptydir"
    empty.mkdir()
    assert main(["history", "--db", str(history_db), "--csv", "-o", str(empty)]) == 2
    assert f"cannot write {empty}: it is a folder" in _one_line(capsys.readouterr().err)


def test_fit_to_a_full_disk(tiny, full_dir, capsys):
    out = full_dir / "x.jsonl"
    assert main(["fit", str(tiny), "-o", str(out)]) == 74
    line = _one_line(capsys.readouterr().err)
    assert f"disk full at {out}: No space left on device; free space or write elsewhere" in line
    assert not out.exists()                                         # the partial file is removed


def test_history_and_plot_to_a_full_disk(history_db, fit_file, full_dir, capsys):
    out = full_dir / "h.csv"
    assert main(["history", "--db", str(history_db), "--csv", "-o", str(out)]) == 74
    assert f"disk full at {out}" in _one_line(capsys.readouterr().err)
    assert not out.exists()
    png = full_dir / "p.png"
    assert main(["plot", "fit", str(fit_file), "-o", str(png)]) == 74
    assert f"disk full at {png}" in _one_line(capsys.readouterr().err)
    assert not png.exists()


def test_standard_output_on_a_full_disk(tiny, history_db):
    with open("/dev/full", "w") as full:
        for args in (("fit", str(tiny)), ("history", "--db", str(history_db), "--csv"),
                     ("events", "--json", "--journal", str(history_db.with_name("events.sqlite3"))),
                     ("config", "template")):                       # the last line of defence in posed.cli
            r = posed(*args, stdout=full)
            assert r.returncode == 74, (args, r.stderr)
            line = _one_line(r.stderr)
            assert "disk full at standard output (/dev/full): No space left on device" in line, (args, line)
    assert not (history_db.parent / "events.sqlite3").exists()


def test_a_closed_pipe_ends_quietly(tiny):
    p = subprocess.Popen([sys.executable, "-m", "posed", "fit", str(tiny)], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    p.stdout.close()                                  # the reader is gone before anything is written
    err = p.stderr.read()
    assert p.wait(timeout=120) == 141, err
    assert "Traceback" not in err and "BrokenPipe" not in err and "Exception ignored" not in err, err
