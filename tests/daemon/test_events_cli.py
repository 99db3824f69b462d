"""``posed events`` and ``posed plot history`` read the event journal read-only: a journal they cannot read is
reported (non-zero exit, stderr), never moved aside, repaired or shown as "no events"."""

from __future__ import annotations

import json
import math
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from posed.cli import main
from posed.daemon.history.store import AngleHistory
from posed.daemon.outbox.journal import EventJournal
from posed.daemon.version import __version__
from posed.falls.config import FallsConfig
from posed.falls.event import FallEvent
from posed.fitting import JOINT_ANGLE_NAMES, FitResult

ROOT = Path(__file__).resolve().parents[2]
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


def test_a_journal_the_daemon_is_creating_lists_no_event_yet(tmp_path, capsys):
    """The file exists and its table is not committed yet (the daemon's first fall event, this moment): a reader
    polling then (a hook, a monitor) gets the listing of no journal yet and exit 0, not a failure."""
    path = tmp_path / "events.sqlite3"
    sqlite3.connect(path).close()
    assert main(["events", "--journal", str(path)]) == 0
    captured = capsys.readouterr()
    assert "no event journal" in captured.out and captured.err == ""
    assert main(["events", "--journal", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["events"] == []
    assert path.stat().st_size == 0


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
    import posed.commands.history as history_cmd
    import posed.commands.plot as plot_cmd

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


def _fall_recording(path) -> None:
    """A landmark recording of a scripted fall (bench.falls_scenarios), for the real daemon to detect."""
    from posed.bench import falls_scenarios as scenarios
    from posed.landmarks import LandmarkFrame, RecordingHeader, write_recording
    from tests.daemon.plan_stages import FALL_SCENARIO

    sc = next(s for s in scenarios.catalogue("tune") if s.name == FALL_SCENARIO)
    frames = [LandmarkFrame(fr.seq, fr.t, fr.landmarks) for fr in scenarios.frames(sc)]
    write_recording(path, RecordingHeader((sc.camera.width, sc.camera.height), sc.fps, source=sc.name,
                                          camera=sc.camera.intrinsics), frames)


def _journal_states(path, starting: bool = False) -> dict[str, float | None]:
    from posed.daemon.outbox.journal_file import JournalError

    try:
        with EventJournal(path, readonly=True) as journal:
            return {s.event.state: s.acked_at for s in journal.query()}
    except JournalError:
        if starting:                      # the file is there, its table not yet: the daemon is creating it
            return {}
        raise


@pytest.mark.timeout(180)
def test_events_ack_against_a_running_daemon(tmp_path):
    """`posed run` on a recorded fall (real fit, real Zenoh), found by `posed events ack` through the same
    config ($POSED_CONFIG): `--state alarm` with the id prefix `posed events` prints acknowledges that message,
    then the id alone acknowledges the rest; the journal the daemon writes says so."""
    from tests.daemon.plan_stages import FALL_OVERRIDES
    from tests.daemon.zenoh_util import free_port

    recording = tmp_path / "fall.landmarks.jsonl"
    _fall_recording(recording)
    state = tmp_path / "state"
    cfg_file = tmp_path / "posed.yaml"
    lines = ["robot_id: acker", f"pipeline: {{state_dir: '{state}'}}",
             f"zenoh: {{listen: ['tcp/127.0.0.1:{free_port()}']}}",
             "falls: {" + ", ".join(o.removeprefix("falls.").replace("=", ": ") for o in FALL_OVERRIDES) + "}",
             f"source: {{type: file, path: '{recording}'}}", "logging: {format: json}"]
    cfg_file.write_text("\n".join(lines) + "\n")
    env = {**os.environ, "POSED_CONFIG": str(cfg_file)}
    proc = subprocess.Popen([sys.executable, "-m", "posed.cli", "run"], cwd=ROOT, env=env,
                            stdout=open(tmp_path / "out.log", "w"), stderr=subprocess.STDOUT)
    journal = state / "events.sqlite3"
    try:
        deadline = time.monotonic() + 120
        while not (journal.is_file() and "alarm" in _journal_states(journal, starting=True)):
            assert proc.poll() is None, (tmp_path / "out.log").read_text()
            assert time.monotonic() < deadline, "no alarm in the journal after 120 s"
            time.sleep(0.2)
        states = _journal_states(journal)
        assert {"falling", "on_floor", "alarm"} <= set(states) and not any(states.values()), states
        # `posed watch` finds the daemon through the same config; the status carries the version
        watch = subprocess.run([sys.executable, "-m", "posed.cli", "watch", "--json", "--seconds", "3"], cwd=ROOT,
                               env=env, capture_output=True, text=True, timeout=60)
        msgs = [json.loads(line) for line in watch.stdout.splitlines()]
        status = [m["value"] for m in msgs if m["key"] == "posed/acker/status"]
        assert status and status[-1]["posed_version"] == __version__, watch.stdout[-2000:] + watch.stderr
        listed = subprocess.run([sys.executable, "-m", "posed.cli", "events"], cwd=ROOT, env=env,
                                capture_output=True, text=True, timeout=60)
        prefix = listed.stdout.splitlines()[1].split()[1]          # the 12-character id column
        ack = subprocess.run([sys.executable, "-m", "posed.cli", "events", "ack", prefix, "--state", "alarm"],
                             cwd=ROOT, env=env, capture_output=True, text=True, timeout=60)
        assert ack.returncode == 0, ack.stdout + ack.stderr
        assert "acknowledged" in ack.stdout and "(alarm)" in ack.stdout
        states = _journal_states(journal)
        assert states["alarm"] is not None
        assert states["falling"] is None and states["on_floor"] is None, "only the alarm was acknowledged"
        ack = subprocess.run([sys.executable, "-m", "posed.cli", "events", "ack", prefix], cwd=ROOT, env=env,
                             capture_output=True, text=True, timeout=60)
        assert ack.returncode == 0, ack.stdout + ack.stderr
        assert all(v is not None for v in _journal_states(journal).values())
        bad = subprocess.run([sys.executable, "-m", "posed.cli", "events", "ack", prefix, "--state", "lying"],
                             cwd=ROOT, env=env, capture_output=True, text=True, timeout=60)
        assert bad.returncode == 2 and "falling, on_floor, alarm, recovered" in bad.stderr.replace("'", "")
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()


def test_events_list_is_the_listing(tmp_path, capsys):
    """deploy/README.md's `posed events list` works, the same as `posed events`."""
    path = tmp_path / "events.sqlite3"
    with EventJournal(path, clock=lambda: 1_700_000_000.0) as journal:
        journal.append(fall("e1", 10.0))
    assert main(["events", "list", "--journal", str(path), "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)
    assert main(["events", "--journal", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == listed and [e["id"] for e in listed["events"]] == ["e1"]


def test_events_ack_without_a_daemon_says_so(tmp_path, capsys):
    from tests.daemon.zenoh_util import free_port

    code = main(["events", "ack", "abc", "--connect", f"tcp/127.0.0.1:{free_port()}", "--wait", "0.5",
                 "--journal", str(tmp_path / "none.sqlite3")])
    assert code == 1
    assert "cannot connect" in capsys.readouterr().err


def test_ack_of_a_state_the_event_does_not_have_says_so_at_once(tmp_path, capsys):
    """issue 34 item 8: `--state alarm` for an event with no alarm message said "is the daemon running?" after
    the wait; the journal tells at once which messages the event has."""
    from tests.daemon.zenoh_util import free_port

    path = tmp_path / "events.sqlite3"
    with EventJournal(path) as journal:
        first = journal.append(fall("e1", 10.0))
        journal.append(FallEvent(id=first.id, robot="r", state="on_floor", t_onset=9.0, t_impact=9.7,
                                 t_detect=11.0, confidence=0.8))
    t0 = time.monotonic()
    code = main(["events", "ack", "e1", "--state", "alarm", "--connect", f"tcp/127.0.0.1:{free_port()}",
                 "--wait", "5", "--journal", str(path)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "has no 'alarm' message" in err and "falling, on_floor" in err and "daemon running" not in err
    assert time.monotonic() - t0 < 4.0
