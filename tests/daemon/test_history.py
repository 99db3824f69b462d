"""Joint-angle history: rate limit, CSV export round trip, downsampling and retention, CLI and plot."""

from __future__ import annotations

import io
import math
import sqlite3
from dataclasses import replace

import cv2

from posed.cli import main
from posed.daemon.history.store import ANGLE_COLUMNS, DOWN_COLUMNS, AngleHistory, read_csv
from posed.daemon.outbox.journal import EventJournal
from posed.falls.config import FallsConfig
from posed.falls.event import FallEvent
from posed.fitting import JOINT_ANGLE_NAMES, FitResult


def result(seq: int, t: float) -> FitResult:
    angles = {name: round(10 * math.sin(0.3 * seq + i) + i, 4) for i, name in enumerate(JOINT_ANGLE_NAMES)}
    angles["theta_kn_l"] = 120.0 * min(1.0, t / 2.0)          # a fall-like knee flexion
    variables = {"theta_bd": 5.0 + seq, "phi_bd": -1.5, "psi_bd": 30.0}
    return FitResult(seq=seq, t=t, ok=True, joint_angles_deg=angles, variables=variables)


def test_rate_limit_and_csv_round_trip(tmp_path):
    with AngleHistory(tmp_path / "h.sqlite3", FallsConfig(history_rate_hz=5.0)) as hist:
        kept = [hist.add(result(i, i / 30.0), wall=1_700_000_000 + i / 30.0) for i in range(90)]
        assert hist.add(FitResult.failure(90, 3.0, "no person")) is False
        assert sum(kept) == 15  # 3 s at 5 Hz
        buf = io.StringIO()
        n = hist.export_csv(buf)
    assert n == 15
    rows = read_csv(buf.getvalue())
    expected = [result(i, i / 30.0) for i in range(90) if kept[i]]
    for row, res in zip(rows, expected, strict=True):
        assert row["seq"] == res.seq and row["t"] == res.t and row["level"] == 0
        for name in JOINT_ANGLE_NAMES:   # the measured ones; the model's fixed angles never are (unknown)
            assert row[name] == (res.joint_angles_deg[name] if name in res.measured.angles else None)
        assert row["theta_bd"] == res.variables["theta_bd"] and row["theta_hd"] is None
    assert rows[0]["wall_time"].startswith("2023-11-14T22:13:20")


def test_since_until_and_unknown_angles(tmp_path):
    with AngleHistory(tmp_path / "h.sqlite3", FallsConfig(history_rate_hz=10.0)) as hist:
        for i in range(50):
            r = result(i, i / 10.0)
            if i == 7:
                r = FitResult(seq=7, t=0.7, ok=True, joint_angles_deg={"theta_hp_l": float("nan")})
            hist.add(r, wall=1000.0 + i)
        rows = list(hist.rows(since=1005.0, until=1010.0))
    assert [r[2] for r in rows] == [5, 6, 7, 8, 9, 10]
    hp = ANGLE_COLUMNS.index("theta_hp_l")
    assert rows[2][4 + hp] is None   # NaN and missing angles are stored as unknown


def test_downsampling_and_retention(tmp_path):
    cfg = FallsConfig(history_rate_hz=10.0, history_downsample_after_h=1.0, history_downsample_period_s=10.0, history_retention_days=1.0)
    now = 10 * 86400.0
    with AngleHistory(tmp_path / "h.sqlite3", cfg, clock=lambda: now) as hist:
        for i in range(100):          # 2 days old: deleted
            hist.add(result(i, i / 10.0), wall=now - 2 * 86400 + i / 10.0)
        for i in range(100, 400):     # 2 hours old, 30 s at 10 Hz: averaged into 10 s buckets
            hist.add(result(i, i / 10.0), wall=now - 7200 + (i - 100) / 10.0)
        for i in range(400, 450):     # fresh: kept as is
            hist.add(result(i, i / 10.0), wall=now - 60 + (i - 400) / 10.0)
        counts = hist.maintain()
        assert counts["deleted"] == 100 and counts["downsampled"] == 300
        rows = list(hist.rows())
        assert hist.maintain()["downsampled"] == 0          # idempotent
    levels = [r[3] for r in rows]
    assert levels.count(1) == 3 and levels.count(0) == 50
    kn = ANGLE_COLUMNS.index("theta_kn_l")
    first_bucket = [result(i, i / 10.0).joint_angles_deg["theta_kn_l"] for i in range(100, 200)]
    assert math.isclose(rows[0][4 + kn], sum(first_bucket) / 100, rel_tol=1e-9)


def test_cli_csv_export_and_plot(tmp_path, capsys):
    state = tmp_path / "state"
    with AngleHistory(state / "history.sqlite3", FallsConfig(history_rate_hz=10.0)) as hist:
        for i in range(60):
            hist.add(result(i, i / 10.0), wall=1_700_000_000 + i / 10.0)
    with EventJournal(state / "events.sqlite3", clock=lambda: 1_700_000_003.0) as journal:
        journal.append(FallEvent(id="e", robot="r", state="falling", t_onset=1.0, t_impact=2.0, t_detect=2.3,
                                 confidence=0.8))
    common = ["--set", f"pipeline.state_dir={state}"]
    csv_out = tmp_path / "out.csv"
    assert main(["history", *common, "--since", "1699999999", "--until", "1700000002.95", "--csv",
                 "-o", str(csv_out)]) == 0
    rows = read_csv(csv_out.read_text())
    assert len(rows) == 30 and rows[-1]["seq"] == 29
    assert main(["history", *common, "--since", "1699999999"]) == 0
    assert "60 frames" in capsys.readouterr().out
    png = tmp_path / "angles.png"
    assert main(["plot", "history", *common, "--since", "1699999999", "-o", str(png)]) == 0
    img = cv2.imread(str(png))
    assert img is not None and img.shape[1] == 1200 and img.shape[0] > 500
    red = (img[:, :, 2] > 200) & (img[:, :, 0] < 60) & (img[:, :, 1] < 60)
    assert red.sum() > 100                     # the fall event's marker and the red hip/torso lines
    assert (img < 250).any(axis=2).mean() > 0.02
    assert main(["plot", "history", *common, "--panels", "nonsense", "-o", str(png)]) == 2
    assert "unknown panel or angle" in capsys.readouterr().err


def test_cli_reports_missing_history(tmp_path, capsys):
    assert main(["history", "--db", str(tmp_path / "none.sqlite3"), "--csv"]) == 2
    assert "no joint-angle history" in capsys.readouterr().err
    assert main(["history", "--db", str(tmp_path / "none.sqlite3"), "--since", "last tuesday"]) == 2
    assert "is not a time" in capsys.readouterr().err


def test_events_cli_lists_journal(tmp_path, capsys):
    import json

    state = tmp_path / "state"
    with EventJournal(state / "events.sqlite3", clock=lambda: 1_700_000_000.0) as journal:
        journal.append(FallEvent(id="e1", robot="r", state="falling", t_onset=1.0, t_impact=2.0, t_detect=2.3,
                                 confidence=0.8, features=("pelvis_descent_fast",)))
        journal.append(FallEvent(id="e1", robot="r", state="alarm", t_onset=1.0, t_impact=2.0, t_detect=12.0,
                                 confidence=0.9))
        journal.acknowledge("e1", "falling")
    assert main(["events", "--set", f"pipeline.state_dir={state}", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert [(e["id"], e["state"], e["acked_at"] is not None) for e in data["events"]] == \
        [("e1", "falling", True), ("e1", "alarm", False)]
    assert main(["events", "--set", f"pipeline.state_dir={state}", "--unacked"]) == 0
    text = capsys.readouterr().out
    assert "alarm" in text and "falling" not in text.split("\n", 1)[1]
    assert main(["events", "--set", f"pipeline.state_dir={tmp_path / 'empty'}"]) == 0
    assert "no event journal" in capsys.readouterr().out


def test_recorder_adds_on_capture_time_and_maintains_about_once_a_minute(tmp_path):
    import time

    from posed.daemon import clock
    from posed.daemon.history.recorder import HistoryRecorder
    from tests.daemon.fakes import RecordingLog

    class Store:
        def __init__(self) -> None:
            self.added, self.maintained, self.closed = [], 0, False

        def add(self, res, wall):
            self.added.append((res.seq, wall))

        def maintain(self):
            self.maintained += 1
            raise OSError("disk gone")

        def close(self):
            self.closed = True

    store, log = Store(), RecordingLog()
    rec = HistoryRecorder(store, log, maintain_every_s=60.0, now=0.0)
    rec.add(result(1, 0.0), clock.now() - 2.0)                      # captured two seconds ago
    assert store.added[0][0] == 1 and abs(store.added[0][1] - (time.time() - 2.0)) < 0.5
    rec.tick(59.0)
    assert store.maintained == 0
    rec.tick(60.0)
    rec.tick(61.0)
    assert store.maintained == 1 and log.events("error") == ["history_maintenance_failed"]
    rec.close()
    assert store.closed
    off = HistoryRecorder(None, log, now=0.0)                        # falls.history_enabled: false
    off.add(result(2, 0.1), 0.0)
    off.tick(1e6)
    off.close()


def test_each_row_keeps_the_down_its_fit_measured_against(tmp_path):
    """A result fitted against gravity (``down``, fitting.vertical) stores it; one taken as level stores NULLs;
    the CSV carries both."""
    down = [0.0, 0.81915, 0.57358]
    with AngleHistory(tmp_path / "h.sqlite3", FallsConfig(history_rate_hz=100.0)) as hist:
        level = result(0, 0.0)
        tilted = replace(result(1, 0.1), extra={"vertical": "gravity", "down": down})
        assert hist.add(level, wall=1_700_000_000.0) and hist.add(tilted, wall=1_700_000_000.1)
        rows = list(hist.rows(columns=("theta_bd", *DOWN_COLUMNS)))
        buf = io.StringIO()
        hist.export_csv(buf)
    assert rows[0][5:] == (None, None, None) and list(rows[1][5:]) == down
    csv_rows = read_csv(buf.getvalue())
    assert [[r[c] for c in DOWN_COLUMNS] for r in csv_rows] == [[None] * 3, down]


def test_a_history_from_before_the_down_columns_gets_them_and_reads_null(tmp_path):
    """A file written by a posed without DOWN_COLUMNS: opened to write, the columns are added (old rows NULL,
    new rows stored); opened read-only as it is, they read NULL."""
    path = tmp_path / "old.sqlite3"
    db = sqlite3.connect(path)
    db.executescript("CREATE TABLE angles (wall REAL NOT NULL, t REAL NOT NULL, seq INTEGER NOT NULL, "
                     "level INTEGER NOT NULL DEFAULT 0, " + ", ".join(f"{n} REAL" for n in ANGLE_COLUMNS) + ");")
    db.execute("INSERT INTO angles (wall, t, seq, level, theta_bd) VALUES (1.0, 0.0, 0, 0, 7.0)")
    db.commit()
    db.close()
    with AngleHistory(path, readonly=True) as old:
        assert list(old.rows(columns=("theta_bd", *DOWN_COLUMNS))) == [(1.0, 0.0, 0, 0, 7.0, None, None, None)]
        buf = io.StringIO()
        old.export_csv(buf)
    assert read_csv(buf.getvalue())[0]["down_x"] is None
    with AngleHistory(path, FallsConfig(history_rate_hz=100.0)) as hist:
        hist.add(replace(result(1, 0.1), extra={"down": [0.0, 1.0, 0.0]}), wall=2.0)
        got = list(hist.rows(columns=("theta_bd", *DOWN_COLUMNS)))
    assert got[0][5:] == (None, None, None) and got[1][5:] == (0.0, 1.0, 0.0)
