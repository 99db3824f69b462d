"""Plots and the daily report, from a history database and journal made by replaying real recordings with a
fall (tests/viz/day.py): clock axis in the robot's zone, plain names, fall markers that do not overlap,
unmeasured angles absent, and a report that holds everything inline."""

from __future__ import annotations

import base64
import datetime as dt
import re
from zoneinfo import ZoneInfo

import cv2
import numpy as np
import pytest

from posed.cli import main
from posed.commands._history_series import angle_series, event_marks
from posed.daemon.history.store import ANGLE_COLUMNS, AngleHistory
from posed.daemon.history.watched import WatchLog
from posed.daemon.outbox.journal import EventJournal
from posed.viz import posture
from posed.viz.names import FIXED_ANGLES, PANELS, label
from posed.viz.plots import angle_figure
from posed.viz.series import AngleSeries, Episode, episodes
from tests.viz.day import build_day

TZ = ZoneInfo("America/New_York")   # not the machine's zone (UTC here): the axis must follow --tz
DAY = dt.date(2026, 7, 14)          # summer time: UTC-04:00


@pytest.fixture(scope="module")
def day(tmp_path_factory, shared_data):
    folder = tmp_path_factory.mktemp("day")
    written = build_day(folder, shared_data, DAY, TZ)
    assert written["rows"] > 50 and any(s == "falling" for _, s, _ in written["events"])
    return folder, written


def _series_and_falls(folder):
    with AngleHistory(folder / "history.sqlite3", readonly=True) as h:
        rows = list(h.rows())
    with EventJournal(folder / "events.sqlite3", readonly=True) as j:
        falls = episodes(event_marks(j.query()))
    return angle_series(rows, ANGLE_COLUMNS), falls


def test_history_plot_reads_as_clock_time_with_plain_names_and_fall_markers(day):
    folder, written = day
    series, falls = _series_and_falls(folder)
    assert len(falls) == len({eid for eid, _, _ in written["events"]}) >= 2
    fig = angle_figure(series, [(k, PANELS[k]) for k in ("legs", "trunk")], falls, title="t", tz=TZ)
    fig.canvas.draw()
    axes = fig.axes
    ticks = [t.get_text() for t in axes[-1].get_xticklabels() if t.get_text()]
    # the sessions run 08:10 .. 19:20 local (New York): clock ticks of that day, in that zone
    hours = [int(m.group(1)) for t in ticks if (m := re.fullmatch(r"(\d\d):00", t))]
    assert hours and min(hours) >= 8 and max(hours) <= 20
    assert "America/New_York, UTC-04:00" in axes[-1].get_xlabel()
    legend = [t.get_text() for ax in axes for t in ax.get_legend().get_texts()]
    assert "left knee flexion" in legend and "right hip flexion" in legend
    assert not any(label(n) in legend for n in FIXED_ANGLES) and not any("theta" in t for t in legend)
    styles = {line.get_label(): line.get_linestyle() for line in axes[0].get_lines() if line.get_label()[0] != "_"}
    assert styles["left knee flexion"] == "-" and styles["right knee flexion"] == "--"
    marks = [c for c in axes[0].texts if c.get_text().startswith("fall ")]
    assert len(marks) == len(falls)          # hours apart: one label each
    boxes = [m.get_window_extent() for m in marks]
    assert not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])


def test_fall_markers_close_together_do_not_overlap():
    t = np.arange(0, 600, 1.0) + 1.78e9
    series = AngleSeries(t, {"theta_kn_l": np.full(len(t), 20.0)}, clock=True)
    falls = [Episode(str(i), 1.78e9 + 100 + 3 * i, 1.78e9 + 110 + 3 * i, ("falling",)) for i in range(5)]
    fig = angle_figure(series, [("legs", PANELS["legs"])], falls, title="t", tz=TZ)
    fig.canvas.draw()
    marks = [c for c in fig.axes[0].texts if c.get_text().startswith("fall")]
    boxes = [m.get_window_extent() for m in marks]
    assert [m.get_text() for m in marks] == ["falls 1-5"]    # 3 s apart on a 10 min axis: one label
    falls += [Episode("6", 1.78e9 + 400, 1.78e9 + 401, ("falling",))]
    fig = angle_figure(series, [("legs", PANELS["legs"])], falls, title="t", tz=TZ)
    fig.canvas.draw()
    marks = [c for c in fig.axes[0].texts if c.get_text().startswith("fall")]
    assert [m.get_text() for m in marks] == ["falls 1-5", "fall 6"]
    boxes = [m.get_window_extent() for m in marks]
    assert not boxes[0].overlaps(boxes[1])


def test_unmeasured_angles_are_gaps_not_zero():
    from posed.fitting import FitResult

    ok = FitResult(0, 0.0, True, joint_angles_deg={"theta_kn_l": 30.0, "theta_el_l": 0.0, "theta_hd": 0.0},
                   variables={"theta_bd": 1.0}, extra={"unobserved": ["theta_el_l"]})
    bad = FitResult.failure(1, 0.1, "no person")
    s = AngleSeries.from_fits([ok, bad, ok])
    assert "theta_hd" not in s.angles                       # held fixed by the model: never a series
    assert np.isnan(s.angles["theta_el_l"]).all()           # not observed in that frame
    assert s.angles["theta_kn_l"][0] == 30.0 and np.isnan(s.angles["theta_kn_l"][1])
    assert not s.clock and s.time[0] == 0.0


def test_plot_commands_write_pngs(day, tmp_path, capsys):
    folder, _ = day
    png = tmp_path / "h.png"
    assert main(["plot", "history", "--db", str(folder / "history.sqlite3"), "--since", "2026-07-01",
                 "--tz", "America/New_York", "-o", str(png)]) == 0
    img = cv2.imread(str(png))
    assert img is not None and img.shape[1] == 1200
    assert main(["plot", "history", "--db", str(folder / "history.sqlite3"), "--tz", "Mars/Olympus",
                 "-o", str(png)]) == 2
    assert "unknown time zone" in capsys.readouterr().err


def test_posture_rules_on_the_model():
    up = {"theta_bd": 0.0, "phi_bd": 0.0, "psi_bd": 0.0}
    assert posture.classify({**up, "theta_hp_l": 0.0, "theta_hp_r": 0.0}) == "standing"
    assert posture.classify(up) is None          # no thigh measured: standing and sitting look alike
    assert posture.classify({"theta_bd": 0.0, "phi_bd": 0.0, "psi_bd": 0.0, "theta_hp_l": 90.0,
                             "theta_hp_r": 90.0, "theta_kn_l": 90.0, "theta_kn_r": 90.0}) == "sitting"
    assert posture.classify({"theta_bd": 90.0, "phi_bd": 0.0, "psi_bd": 0.0}) == "lying"
    assert posture.classify({"theta_bd": 0.0, "phi_bd": 85.0, "psi_bd": 0.0}) == "lying"
    trunk, thigh = posture.inclinations({"theta_bd": 30.0, "phi_bd": 0.0, "psi_bd": 0.0})
    assert trunk == pytest.approx(30.0, abs=0.5) and thigh == pytest.approx(30.0, abs=0.5)


def test_posture_is_measured_against_the_camera_s_down_when_it_is_known():
    """Seen by a camera 35 degrees down: a person lying on their back, head towards it (the trunk along its
    view), reads 55 degrees from the vertical against the camera taken as level (not lying), 90 against its
    down; a person standing reads 35 and 0."""
    from posed.falls.features import gravity_from_tilt
    from posed.fitting.kinematics import body_angles_from_rotation, body_rotation
    from posed.fitting.vertical import level_frame

    down = gravity_from_tilt(35.0)

    def seen(theta_bd: float, psi_bd: float) -> dict:
        """The stored angles (body angles against the camera) of a body with these angles against gravity."""
        t, p, q = body_angles_from_rotation(level_frame(down) @ body_rotation(theta_bd, 0.0, psi_bd))
        return {"theta_bd": t, "phi_bd": p, "psi_bd": q, "theta_hp_l": 0.0, "theta_hp_r": 0.0}

    lying, standing = seen(-90.0, 0.0), seen(0.0, 30.0)
    assert posture.classify(lying, down) == "lying" and posture.classify(lying) != "lying"
    assert posture.inclinations(lying, down)[0] == pytest.approx(90.0, abs=0.5)
    assert posture.inclinations(lying)[0] == pytest.approx(55.0, abs=0.5)
    assert posture.classify(standing, down) == posture.classify(standing) == "standing"
    assert posture.inclinations(standing, down)[0] == pytest.approx(0.0, abs=0.5)
    assert posture.inclinations(standing)[0] == pytest.approx(35.0, abs=0.5)
    assert "looking 35 degrees down" in " ".join(posture.method_text(down))
    # the day's summary takes each sample's own down (the history's down_x, down_y, down_z: a robot that
    # tilts its head), before the one given for samples fitted without one
    series = {k: np.array([lying[k], lying[k]]) for k in lying}
    series.update({f"down_{a}": np.array([v, np.nan]) for a, v in zip("xyz", down, strict=True)})
    day = posture.summarise(np.array([0.0, 1.0]), series, (0.0, 2.0), 1.0)
    assert day.seconds["lying"] == pytest.approx(1.0)            # the first sample only: the second has no down
    day = posture.summarise(np.array([0.0, 1.0]), series, (0.0, 2.0), 1.0, down)
    assert day.seconds["lying"] == pytest.approx(2.0)


def test_the_report_takes_the_measured_mount_or_the_learned_geometry_as_down(tmp_path):
    import json
    from dataclasses import replace

    from posed.commands.report import camera_down
    from posed.daemon.config.schema import Config
    from posed.daemon.stages.fall_watch import geometry_file
    from posed.falls.camera_geometry import CameraGeometry
    from posed.falls.features import gravity_from_tilt

    c = Config()
    assert camera_down(c, tmp_path) is None                                  # nothing known: level
    measured = replace(c, falls=replace(c.falls, camera_tilt_deg=30.0))
    np.testing.assert_allclose(camera_down(measured, tmp_path), gravity_from_tilt(30.0))
    # the fall detector learned the camera from a standing person (its axis 22 degrees from the level guess)
    geometry = CameraGeometry(c.falls)
    for _ in range(30):
        geometry.observe_body_axis(-gravity_from_tilt(22.0), 0.1)
    assert geometry.used()["gravity"] == "body"
    path = geometry_file(tmp_path, c.source)
    path.write_text(json.dumps(geometry.state()))
    np.testing.assert_allclose(camera_down(c, tmp_path), gravity_from_tilt(22.0), atol=1e-9)
    path.write_text(json.dumps(CameraGeometry(c.falls).state()))
    assert camera_down(c, tmp_path) is None                                  # nothing was learned
    path.write_text("{not json")
    assert camera_down(c, tmp_path) is None                                  # unreadable: made without it

def test_report_is_one_self_contained_html_with_the_day(day, tmp_path):
    folder, written = day
    out = tmp_path / "r.html"
    assert main(["report", "--day", DAY.isoformat(), "--db", str(folder / "history.sqlite3"),
                 "--tz", "America/New_York", "-o", str(out)]) == 0
    text = out.read_text()
    assert not re.search(r"(src|href)=['\"](?!data:)", text)          # nothing loaded from anywhere
    pngs = re.findall(r"data:image/png;base64,([A-Za-z0-9+/=]+)", text)
    assert len(pngs) >= 2
    for p in pngs:
        img = cv2.imdecode(np.frombuffer(base64.b64decode(p), np.uint8), cv2.IMREAD_COLOR)
        assert img is not None and img.shape[0] > 100
    for word in ("standing", "sitting", "lying", "watching, nobody in view", "sit-to-stand", "walking bouts",
                 "left knee flexion", "how it ended"):
        assert word in text
    # posed was off from 01:00 to 07:00 (tests/viz/day.py): the report says so, and says the falls against it
    assert "not watching for 6 h 00 min" in text
    assert re.search(r"<td class='warn'>not watching \(posed off or no camera\)</td><td>6 h 00 min</td>", text)
    assert "No fall was detected" not in text
    assert "elbow" not in text.split("Joint-angle ranges")[1].split("</table>")[0]   # never seen: not listed
    first_id, _, first_at = written["events"][0]
    started = dt.datetime.fromtimestamp(first_at, TZ).strftime("%H:%M:%S")
    acked = dt.datetime.fromtimestamp(first_at + 95.0, TZ).strftime("%H:%M:%S")
    assert re.search(rf"<td>fall 1</td><td>{started}</td>.*<td>{acked}</td>", text)
    n_falls = len({eid for eid, _, _ in written["events"]})
    assert text.count("<td>fall ") == n_falls
    assert "<b class='warn'>no</b>" in text                             # the second fall was never acknowledged


def test_plot_fit_takes_the_start_in_the_plot_zone_and_marks_posed_falls_events(shared_data, tmp_path, capsys):
    from posed.commands.plot import _start_time

    assert _start_time("2026-07-14T10:00:00", TZ) == dt.datetime(2026, 7, 14, 14, 0, tzinfo=dt.UTC).timestamp()
    assert _start_time("2026-07-14T10:00:00Z", TZ) == dt.datetime(2026, 7, 14, 10, 0, tzinfo=dt.UTC).timestamp()
    rec = shared_data / "falls" / "urfd_dev" / "urfd_04_fall.landmarks.jsonl"
    fit, events = tmp_path / "fit.jsonl", tmp_path / "events.jsonl"
    assert main(["fit", str(rec), "-o", str(fit)]) == 0
    geometry = ["--set", "falls.camera_height_m=0.85"]
    assert main(["falls", str(rec), *geometry]) == 0
    events.write_text(capsys.readouterr().out)
    assert events.read_text().strip(), "posed falls found no fall in urfd_04 (the detector changed?)"
    png = tmp_path / "fit.png"
    assert main(["plot", "fit", str(fit), "--events", str(events), "--start", "2026-07-14T10:00:00",
                 "--tz", "America/New_York", "-o", str(png)]) == 0
    assert "1 fall event(s)" in capsys.readouterr().err
    assert cv2.imread(str(png)) is not None


def test_a_day_not_over_never_counts_its_future_and_an_empty_day_is_not_a_day_without_falls(day):
    from posed.viz.report import day_report

    folder, written = day
    series, falls = _series_and_falls(folder)
    with WatchLog(folder / "history.sqlite3", readonly=True) as w:
        watched = w.minutes(0, 4e9)
    now = dt.datetime.combine(DAY, dt.time(15, 30), TZ).timestamp()     # the report made at 15:30
    text = day_report(series, [f for f in falls if f.start < now], DAY, TZ, robot="r", sources="s",
                      watched=[r for r in watched if r[0] < now], now=now)
    assert "up to 15:30:00" in text
    assert re.search(r"not yet \(the day is not over\)</td><td class='small'>8 h 30 min</td>", text)
    # 15 h 30 min so far, 6 h of them off: the table's rows make the 15 h 30 min, nothing after 15:30
    assert re.search(r"<td class='warn'>not watching \(posed off or no camera\)</td><td>6 h 00 min</td>", text)
    assert "watching for <b>9 h 30 min</b> of 15 h 30 min" in text
    # a day with nothing at all: posed was not watching, never "no fall"
    empty = day_report(AngleSeries(np.zeros(0), {}, True), [], dt.date(2026, 7, 20), TZ, robot="r", sources="s",
                       watched=[], now=now + 30 * 86400)
    assert "posed was not watching at all this day" in empty and "No fall was detected" not in empty
    assert "posed was not watching this day: it cannot say whether anyone fell" in empty
    # a history written before posed recorded when it watched: it says it cannot tell
    old = day_report(series, falls, DAY, TZ, robot="r", sources="s", watched=None, now=now + 86400)
    assert "does not record when posed was watching" in old


def test_the_day_grid_has_posture_colours_and_fall_labels_that_never_overlap(day):
    from matplotlib.colors import to_hex

    from posed.viz.report import MINUTE_STYLE, day_grid_figure, minute_states

    folder, _ = day
    series, falls = _series_and_falls(folder)
    start = dt.datetime.combine(DAY, dt.time(0), TZ).timestamp()
    span = (start, start + 86400.0)
    with WatchLog(folder / "history.sqlite3", readonly=True) as w:
        watched = w.minutes(*span)
    summary = posture.summarise(series.time, series.angles, span, 1.0)
    states = minute_states(summary, watched, span, span[1] + 1)
    assert len(states) == 1440 and states[60:420] == ["not watching (posed off or no camera)"] * 360
    assert {"standing", "watching, nobody in view"} <= set(states)
    # seven falls in one hour (a looping replay), and two more elsewhere: one label per hour, none overlapping
    assert [int((f.start - start) // 3600) for f in falls] == [10, 17]
    many = sorted([Episode(str(i), start + 12 * 3600 + 60 * i, start + 12 * 3600 + 60 * i + 5, ("falling",))
                   for i in range(7)] + falls, key=lambda f: f.start)
    fig = day_grid_figure(states, many, span, TZ)
    fig.canvas.draw()
    labels = [t for t in fig.axes[0].texts if t.get_text().startswith("fall")]
    assert sorted(t.get_text() for t in labels) == ["fall 1", "fall 9", "falls 2-8"]
    boxes = [t.get_window_extent() for t in labels]
    assert not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])
    colours = {to_hex(p.get_facecolor()) for p in fig.axes[0].patches if p.get_fill()}
    assert MINUTE_STYLE["standing"][0] in colours and MINUTE_STYLE["sitting"][0] in colours
    assert MINUTE_STYLE["watching, nobody in view"][0] in colours


def test_plot_fit_ticks_are_distinct_and_fall_labels_stay_off_the_headings():
    for span in (4.5, 65.0, 900.0):
        t = np.linspace(0, span, 200)
        series = AngleSeries(t, {"theta_kn_l": np.full(len(t), 20.0)}, clock=False)
        falls = [Episode("1", 0.02 * span, 0.3 * span, ("falling", "on_floor"))]   # at the left, by the title
        fig = angle_figure(series, [("legs", PANELS["legs"]), ("trunk", PANELS["trunk"])], falls, title="t",
                           acks=False)
        fig.canvas.draw()
        ticks = [x.get_text() for x in fig.axes[-1].get_xticklabels() if x.get_text()]
        assert len(ticks) >= 4 and len(set(ticks)) == len(ticks), ticks
        [mark] = [c for c in fig.axes[0].texts if c.get_text() == "fall 1"]
        title = fig.axes[0].title if fig.axes[0].title.get_text() else fig.axes[0]._left_title
        assert not mark.get_window_extent().overlaps(title.get_window_extent())


def test_posed_history_speaks_plain_names_and_names_the_file_it_reads(day, tmp_path, capsys):
    folder, _ = day
    assert main(["history", "--db", str(folder / "history.sqlite3")]) == 0
    out, err = capsys.readouterr()
    assert f"reading {folder / 'history.sqlite3'} (--db)" in err
    assert "left knee flexion" in out and "theta" not in out and "head flexion" not in out
    assert "not seen in this time range: left shoulder flexion" in out      # no elbows in these recordings
    assert main(["history", "--set", f"pipeline.state_dir={tmp_path}"]) == 2
    err = capsys.readouterr().err
    assert f"reading {tmp_path / 'history.sqlite3'} (pipeline.state_dir;" in err
