"""``posed events`` and ``posed plot history`` read the event journal read-only: a journal they cannot read is
reported (non-zero exit, stderr), never moved aside, repaired or shown as "no events"."""

from __future__ import annotations

import json
import math
import sqlite3

from daemon.cli import main
from daemon.history.store import AngleHistory
from daemon.outbox.journal import EventJournal
from falls.config import FallsConfig
from falls.event import FallEvent
from fitting import JOINT_ANGLE_NAMES, FitResult

GARBAGE = b"this is not a database" * 100


def fall(id_: str, t: float) -> FallEvent:
    return FallEvent(id=id_, robot="r", state="falling", t_onset=t - 1.0, t_impact=t - 0.3, t_detect=t,
                     confidence=0.8)


def write_history(path) -> None:
    with AngleHistory(path, FallsConfig(history_rate_hz=10.0)) as hist:
        for i in range(30):
            angles = {name: 10.0 * math.sin(0.3 * i + k) for k, name in enumerate(JOINT_ANGLE_NAMES)}
            hist.add(FitResult(seq=i, t=i / 10.0, ok=True, joint_angles_deg=angles,
                               variables={"theta_bd": 5.0, "phi_bd": 0.0, "psi_bd": 30.0}),
                     wall=1_700_000_000 + i / 10.0)


def test_unacked_is_applied_before_limit(tmp_path, capsys):
    path = tmp_path / "events.sqlite3"
    clock = iter(range(1_700_000_000, 1_700_000_100)).__next__
    with EventJournal(path, clock=lambda: float(clock())) as journal:
        for i in range(8):
            journal.append(fall(f"e{i}", 10.0 + i))
        for i in (5, 6, 7):                      # the newest three are acknowledged
            journal.acknowledge(f"e{i}")
        assert [s.event.id for s in journal.query(limit=2, unacked=True)] == ["e3", "e4"]
    assert main(["events", "--journal", str(path), "--limit", "2", "--unacked", "--json"]) == 0
    ids = [e["id"] for e in json.loads(capsys.readouterr().out)["events"]]
    assert ids == ["e3", "e4"]                   # the newest two unacknowledged, not "none of the newest two"


def test_events_reports_a_corrupt_journal_and_leaves_it_alone(tmp_path, capsys):
    path = tmp_path / "events.sqlite3"
    path.write_bytes(GARBAGE)
    assert main(["events", "--journal", str(path), "--json"]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""                    # no log line and no empty JSON on stdout
    assert str(path) in captured.err and "cannot read the event journal" in captured.err
    assert ".recover" in captured.err
    assert path.read_bytes() == GARBAGE
    assert sorted(p.name for p in tmp_path.iterdir()) == ["events.sqlite3"]


def test_events_reports_a_file_that_is_no_journal_without_changing_it(tmp_path, capsys):
    path = tmp_path / "other.sqlite3"
    db = sqlite3.connect(path)
    db.execute("CREATE TABLE notes (text TEXT)")
    db.commit()
    db.close()
    assert main(["events", "--journal", str(path)]) == 1
    captured = capsys.readouterr()
    assert "no events" not in captured.out
    assert str(path) in captured.err and "not an event journal" in captured.err
    tables = sqlite3.connect(path).execute("SELECT name FROM sqlite_master WHERE type = 'table'").fetchall()
    assert tables == [("notes",)]


def test_missing_journal_is_still_a_plain_message(tmp_path, capsys):
    missing = tmp_path / "state" / "events.sqlite3"
    assert main(["events", "--journal", str(missing)]) == 0
    assert "no event journal" in capsys.readouterr().out
    assert not missing.parent.exists()


def test_plot_reports_a_corrupt_journal_and_leaves_it_alone(tmp_path, capsys):
    state = tmp_path / "state"
    write_history(state / "history.sqlite3")
    (state / "events.sqlite3").write_bytes(GARBAGE)
    png = tmp_path / "angles.png"
    assert main(["plot", "history", "--set", f"pipeline.state_dir={state}", "--since", "1699999999",
                 "-o", str(png)]) == 1
    err = capsys.readouterr().err
    assert str(state / "events.sqlite3") in err and "--no-events" in err
    assert (state / "events.sqlite3").read_bytes() == GARBAGE
    assert not list(state.glob("*.corrupt-*"))
    assert main(["plot", "history", "--set", f"pipeline.state_dir={state}", "--since", "1699999999",
                 "--no-events", "-o", str(png)]) == 0
    assert png.is_file()


def test_plot_checks_the_output_name_before_reading(tmp_path, capsys):
    assert main(["plot", "history", "--db", str(tmp_path / "none.sqlite3"), "-o", str(tmp_path / "a.jpg")]) == 2
    assert "must end in .png" in capsys.readouterr().err


def test_plot_loads_the_config_once(tmp_path, monkeypatch):
    import daemon.commands.history as history_cmd
    import daemon.commands.plot as plot_cmd

    state = tmp_path / "state"
    write_history(state / "history.sqlite3")
    with EventJournal(state / "events.sqlite3", clock=lambda: 1_700_000_001.0) as journal:
        journal.append(fall("e", 2.0))
    loads = []
    load = history_cmd.config_from_args

    def counting(args):
        loads.append(args)
        return load(args)

    monkeypatch.setattr(plot_cmd, "config_from_args", counting)
    monkeypatch.setattr(history_cmd, "config_from_args", counting)
    assert main(["plot", "history", "--set", f"pipeline.state_dir={state}", "--since", "1699999999",
                 "-o", str(tmp_path / "a.png")]) == 0
    assert len(loads) == 1
