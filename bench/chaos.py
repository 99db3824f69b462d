"""The chaos campaign (``posed bench chaos``): a real ``posed run`` on a real input, attacked for a bounded time.

Per input (:mod:`bench.chaos_inputs`: the real squat video and a recording of real falls, each with a corrupt
frame every N, replayed in a loop at its own rate) the campaign

1. starts a zenoh-python router (the stand-in for zenohd) and ``posed run`` joining it, with two hooks on
   every fall event: one that hangs (killed at its timeout) and one that prints ``hook_megabytes`` MB;
2. waits for the first pose, then for ``seconds``: at seeded random intervals sends kill -9 or SIGSTOP (for a
   random time, then SIGCONT) to a random stage; runs a subscriber to the fall events that comes and goes;
   puts an ack flood of ``ack_flood`` hostile payloads once, at a random time; an observer receives every
   pose, status and fall event and acknowledges a seeded share of the events;
   with the faults of :mod:`bench.chaos_faults` (issue 34): ``web_idle`` idle connections to the daemon's web
   stage from 15 % to 45 % of the chaos while the page is probed, and the state directory (a tmpfs of its
   own) read-only from 30 %, full from 55 % and freed at 80 %; the inputs may carry crafted oversized JPEG
   headers and clock jumps (:mod:`bench.chaos_inputs`);
3. lets the daemon settle (every stopped process continued; until every journalled message reached the
   observer, at most ``settle_s``), stops it with SIGTERM and reads its journal and its log.

The report counts fall-event messages (one per event id and state): ``produced`` (the publisher's
``fall_event`` log lines), ``journaled`` (rows of events.sqlite3), ``published`` (rows with
``published_at``), ``received`` (by the observer), ``acknowledged`` (rows with ``acked_at``), and
``lost`` = produced or journaled but never received, which must be 0. Also: the longest time without a
pose, the restarts, the memory (PSS sum of all processes) before and after, the exit status, processes
left behind. Times in seconds (monotonic clock), memory in MB.

``alarms`` (:mod:`bench.chaos_alarms`): every fall opened (``falling`` or ``on_floor``) must get exactly one
``alarm`` with its id, on time within ``alarm_grace_s``, unless ``recovered`` came first; ``violations`` must
be 0. To test it under the faults that matter, a stage is killed -9 shortly after each fall event is received
(``midfall_kill_share``; the first such kill hits the publisher, where the open fall lives), and the settle
also waits for the alarms of the falls opened during the chaos (at most ``settle_s``).
"""

from __future__ import annotations

import json
import os
import random
import signal
import socket
import sqlite3
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from posed.bench import chaos_alarms, chaos_bus, chaos_faults, chaos_inputs
from posed.bench.machine import machine

STAGES = ("capture", "landmarks", "fitting", "publisher")


@dataclass(frozen=True)
class ChaosPlan:
    """What the campaign does; every random choice comes from ``seed``."""

    seconds: float = 60.0                       # chaos per input
    seed: int = 0
    inputs: tuple[str, ...] = ("squat", "falls")
    corrupt_every: int = 25                     # one frame in this many is corrupt
    fault_every_s: tuple[float, float] = (4.0, 10.0)    # time between two stage faults
    stop_s: tuple[float, float] = (0.5, 8.0)    # SIGSTOP lasts this long (over 5 s: the watchdog kills it)
    kill_share: float = 0.5                     # share of faults that are kill -9 (the rest SIGSTOP)
    ack_flood: int = 20000
    ack_share: float = 0.5                      # share of fall events the observer acknowledges
    hook_megabytes: int = 50
    hook_hang_timeout_s: float = 5.0
    settle_s: float = 45.0
    events_before_chaos: int = 0                # wait for this many fall-event messages before the chaos
    stage_faults: bool = True                   # False: no kill -9 / SIGSTOP (a control run)
    startup_timeout_s: float = 300.0
    crafted_images: bool = True                 # the squat input carries crafted oversized JPEG headers
    clock_jumps: bool = True                    # the falls input's clock leaps, stands still and goes back
    web_idle: int = 1000                        # idle connections to the web stage (0: the web stage is off)
    storage_faults: bool = True                 # the state directory goes read-only, then full (root only)
    storage_kb: int = 16384                     # the state directory's tmpfs
    midfall_kill_share: float = 1.0             # share of fall events after which a stage is killed -9 before
    #                                             the alarm is due (bench.chaos_alarms.MidFallKills; 0: none)
    alarm_grace_s: float = 15.0                 # an alarm this much later than due is late; an open fall without
    #                                             alarm or recovered by then is missing (a SIGSTOP up to 8 s, the
    #                                             watchdog's 5 s, a restart and its warm-up)


UNIT = Path(__file__).resolve().parents[1] / "deploy" / "posed.service"
SYSTEMD_NOFILE = 1024           # systemd's default soft limit of open files for a service (DefaultLimitNOFILE)


def unit_nofile(unit: Path = UNIT) -> int:
    """The soft limit of open files the shipped unit gives the daemon: its ``LimitNOFILE=`` (soft[:hard]), else
    systemd's default; the campaign runs the daemon under it, as the service would."""
    try:
        for line in unit.read_text().splitlines():
            if line.strip().startswith("LimitNOFILE="):
                return int(line.split("=", 1)[1].split(":")[0].strip())
    except (OSError, ValueError):
        pass
    return SYSTEMD_NOFILE


def _limit_nofile(soft: int) -> None:
    import resource

    _, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (min(soft, hard), hard))


def _free_port() -> int:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def _hooks(token: str, megabytes: int, hang_timeout_s: float) -> str:
    hang = [sys.executable, "-c", "import time; time.sleep(3600)", token]
    chatty = [sys.executable, "-c", f"import sys; sys.stdout.write('x' * {megabytes * 1_000_000})", token]
    return ("hooks.on_event=[" + f"{{argv: {json.dumps(hang)}, timeout_s: {hang_timeout_s}, retries: 0}}, "
            f"{{argv: {json.dumps(chatty)}, timeout_s: 60, retries: 0}}]")


def _marked_pids(token: str) -> list[int]:
    """Processes whose command line holds ``token`` (the campaign's hooks)."""
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if token.encode() in (d / "cmdline").read_bytes():
                    out.append(int(d.name))
            except OSError:
                pass
    return out


def _read_journal(path: Path) -> list[tuple[str, str, float | None, float | None]]:
    if not path.is_file():
        return []
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True, timeout=5)
    try:
        return db.execute("SELECT event_id, state, published_at, acked_at FROM messages").fetchall()
    except sqlite3.Error:
        return []
    finally:
        db.close()


def _log_events(path: Path) -> list[dict]:
    out = []
    with open(path, "rb") as fh:
        for raw in fh:
            try:
                row = json.loads(raw)
            except ValueError:
                continue
            if isinstance(row, dict):
                out.append(row)
    return out


def _signal(pid: int, sig: int) -> bool:
    try:
        os.kill(pid, sig)
        return True
    except ProcessLookupError:
        return False


def _alarm_after_s(overrides: tuple[str, ...]) -> float:
    """``falls.alarm_after_s`` of the daemon the campaign starts: the input's override, else the default."""
    for o in overrides:
        if o.startswith("falls.alarm_after_s="):
            return float(o.split("=", 1)[1])
    from posed.falls.config import FallsConfig

    return float(FallsConfig().alarm_after_s)


def _mem(status: dict | None) -> dict:
    if not status:
        return {}
    pub = status.get("stages", {}).get("publisher", {})
    return {"memory_mb": status.get("memory_mb"), "anon_mb": status.get("anon_mb"),
            "publisher_rss_mb": pub.get("rss_mb")}


def run_input(inp: chaos_inputs.ChaosInput, plan: ChaosPlan, work: Path, seed: int, progress) -> dict:
    """One daemon, one input, the whole campaign; returns its report."""
    rng = random.Random(seed)
    token = f"posed-chaos-{os.getpid()}-{seed}"
    robot = f"chaos{seed}"
    state = work / "state"
    router_ep = f"tcp/127.0.0.1:{_free_port()}"
    cmd = [sys.executable, "-m", "posed.cli", "run", "--source", inp.source,
           "--set", f"pipeline.state_dir={state}", "--set", "logging.format=json", "--set", f"robot_id={robot}",
           "--set", f"zenoh.listen=[tcp/127.0.0.1:{_free_port()}]", "--set", f"zenoh.connect=[{router_ep}]",
           "--set", "source.loop=true", "--set", "zenoh.event_republish_s=2",
           # the campaign restarts stages far more often than the default budget (5 per minute) allows
           "--set", "pipeline.max_restarts=1000",
           "--set", _hooks(token, plan.hook_megabytes, plan.hook_hang_timeout_s)]
    for o in inp.overrides:
        cmd += ["--set", o]
    web_port = _free_port()
    if plan.web_idle:
        cmd += ["--set", "web.enabled=true", "--set", f"web.port={web_port}"]
    storage = chaos_faults.StorageFaults(state, plan.storage_kb) if plan.storage_faults else None
    if storage is not None:
        storage.mount()
    import zenoh

    from posed.client import session_config

    faults = {"kill9": 0, "sigstop": 0, "by_stage": {}, "midfall_kill9": 0}
    kills: list[tuple[float, str]] = []     # (unix time, stage) of every kill -9, for the alarm invariant
    alarm_after_s = _alarm_after_s(inp.overrides)
    midfall = chaos_alarms.MidFallKills(alarm_after_s, plan.midfall_kill_share if plan.stage_faults else 0.0,
                                        seed + 3)
    t_stop_unix = None
    stopped: dict[int, float] = {}          # pid -> when to SIGCONT
    report: dict = {"input": inp.name, "source": inp.source, "frames_per_pass": inp.frames,
                    "corrupt_frames_per_pass": inp.corrupt, "falls_per_pass": inp.falls_per_pass}
    out_log = work / "daemon.out.log"
    with zenoh.open(session_config("router", listen=[router_ep])) as _router, \
            chaos_bus.open_client(router_ep) as session:
        obs = chaos_bus.Observer(session, robot, plan.ack_share, seed)
        nofile = unit_nofile()
        proc = subprocess.Popen(cmd, stdout=open(out_log, "wb"), stderr=open(work / "daemon.err.log", "wb"),
                                start_new_session=True, preexec_fn=lambda: _limit_nofile(nofile))
        report["limit_nofile"] = nofile
        churn = None
        try:
            t_start = time.monotonic()
            while obs.poses_since(0) < 3 or obs.last_status() is None:
                if proc.poll() is not None:
                    raise RuntimeError(f"the daemon exited ({proc.returncode}) before its first pose: "
                                       f"{(work / 'daemon.err.log').read_text()[-2000:]}")
                if time.monotonic() - t_start > plan.startup_timeout_s:
                    raise RuntimeError(f"no pose {plan.startup_timeout_s} s after start")
                time.sleep(0.1)
            while len(obs.received) < plan.events_before_chaos:
                if proc.poll() is not None or time.monotonic() - t_start > plan.startup_timeout_s:
                    raise RuntimeError(f"no {plan.events_before_chaos} fall-event messages before the chaos")
                time.sleep(0.1)
            report["startup_s"] = round(time.monotonic() - t_start, 1)
            before = obs.last_status()
            report["memory_before"] = _mem(before)
            progress(f"{inp.name}: running after {report['startup_s']} s; chaos for {plan.seconds:g} s")
            churn = chaos_bus.ComingAndGoing(router_ep, robot, seed + 1).start()
            t0 = time.monotonic()
            t_end = t0 + plan.seconds
            t_flood = t0 + rng.uniform(0.2, 0.6) * plan.seconds
            next_fault = t0 + rng.uniform(*plan.fault_every_s)
            flood = None
            peak = dict(report["memory_before"])
            idle = chaos_faults.IdleWeb(web_port, plan.web_idle) if plan.web_idle else None
            t_idle = t0 + 0.15 * plan.seconds
            idle_thread = None
            storage_plan = [(0.3, "read_only"), (0.55, "full"), (0.8, "freed")] if storage and storage.mounted \
                else []
            storage_seen: dict[str, int] = {}
            while time.monotonic() < t_end:
                now = time.monotonic()
                if idle is not None and idle_thread is None and now >= t_idle:
                    idle_thread = idle.hold(0.3 * plan.seconds)
                    progress(f"{inp.name}: t={now - t0:5.1f} s {plan.web_idle} idle web connections")
                while storage_plan and now >= t0 + storage_plan[0][0] * plan.seconds:
                    _, what = storage_plan.pop(0)
                    _storage_fault(storage, what, obs, kills)
                    progress(f"{inp.name}: t={now - t0:5.1f} s state directory {what}")
                st_store = (obs.last_status() or {}).get("storage")
                if isinstance(st_store, dict):
                    key = str(st_store.get("state"))
                    storage_seen[key] = storage_seen.get(key, 0) + 1
                for pid, t_cont in list(stopped.items()):
                    if now >= t_cont:
                        _signal(pid, signal.SIGCONT)
                        del stopped[pid]
                if flood is None and now >= t_flood:
                    flood = chaos_bus.ack_flood(session, robot, plan.ack_flood, seed + 2)
                    progress(f"{inp.name}: ack flood of {flood['sent']} in {flood['seconds']} s")
                if plan.stage_faults and now >= next_fault:
                    next_fault = now + rng.uniform(*plan.fault_every_s)
                    st = obs.last_status() or {}
                    stages = [s for s in STAGES if st.get("stages", {}).get(s, {}).get("alive")
                              and st["stages"][s].get("pid") not in stopped]
                    if stages:
                        stage = rng.choice(stages)
                        pid = st["stages"][stage]["pid"]
                        if rng.random() < plan.kill_share:
                            kind = "kill9" if _signal(pid, signal.SIGKILL) else None
                            if kind:
                                kills.append((time.time(), stage))
                        else:
                            kind = "sigstop" if _signal(pid, signal.SIGSTOP) else None
                            stopped[pid] = now + rng.uniform(*plan.stop_s)
                        if kind:
                            faults[kind] += 1
                            faults["by_stage"][stage] = faults["by_stage"].get(stage, 0) + 1
                            progress(f"{inp.name}: t={now - t0:5.1f} s {kind} {stage} (pid {pid})")
                with obs.lock:
                    received = dict(obs.received)
                midfall.offer(received, now)
                for event_id, stage in midfall.due(now):
                    st = obs.last_status() or {}
                    pid = st.get("stages", {}).get(stage, {}).get("pid")
                    if pid and pid not in stopped and _signal(pid, signal.SIGKILL):
                        kills.append((time.time(), stage))
                        faults["midfall_kill9"] += 1
                        faults["by_stage"][stage] = faults["by_stage"].get(stage, 0) + 1
                        progress(f"{inp.name}: t={now - t0:5.1f} s kill9 {stage} (pid {pid}) mid-fall {event_id}")
                cur = _mem(obs.last_status())
                for k, v in cur.items():
                    if v is not None and (peak.get(k) is None or v > peak[k]):
                        peak[k] = v
                if proc.poll() is not None:
                    break
                time.sleep(0.05)
            t_chaos_end = time.monotonic()
            t_chaos_end_unix = time.time()
            if idle_thread is not None:
                idle_thread.join(60)
            for what in ("read_only", "full", "freed"):      # a short chaos: every storage fault still runs
                if storage_plan and storage_plan[0][1] == what:
                    storage_plan.pop(0)
                    _storage_fault(storage, what, obs, kills)
            for pid in stopped:
                _signal(pid, signal.SIGCONT)
            stopped.clear()
            churn.stop()
            report["daemon_survived_chaos"] = proc.poll() is None
            # settle: everything journalled must reach the observer (republished every 2 s)
            journal = state / "events.sqlite3"
            t_settle = time.monotonic()
            while time.monotonic() - t_settle < plan.settle_s and proc.poll() is None:
                rows = _read_journal(journal)
                with obs.lock:
                    missing = [r for r in rows if (r[0], r[1]) not in obs.received]
                st = obs.last_status() or {}
                running = all(x.get("state") == "running" for x in st.get("stages", {}).values())
                # and every fall opened during the chaos is decided, or its alarm overdue by the grace
                due = chaos_alarms.undecided_due(chaos_alarms.read_messages(journal), alarm_after_s,
                                                 t_chaos_end_unix)
                decided = due is None or time.time() > due + plan.alarm_grace_s
                if not missing and running and decided and time.monotonic() - t_settle > 3.0:
                    break
                time.sleep(0.2)
            report["settle_s"] = round(time.monotonic() - t_settle, 1)
            after = obs.last_status()
            gap, gap_at = obs.longest_gap(t0, t_chaos_end)
            report.update(
                chaos_s=round(t_chaos_end - t0, 1), faults=faults, ack_flood=flood,
                subscriber_churn={"cycles": churn.cycles, "event_messages": churn.messages},
                poses=obs.poses_since(t0), longest_publishing_gap_s=round(gap, 2),
                longest_gap_at_s=round(gap_at, 1) if gap_at is not None else None,
                memory_after=_mem(after), memory_peak=peak,
                web=idle.report() if idle is not None else None,
                storage=dict(storage.report(t0), status_states=storage_seen,
                             status_after=(after or {}).get("storage")) if storage is not None else None,
                restarts=(after or {}).get("restarts"), capture=_capture_counts(after),
                # falls the replay showed while the chaos ran (real time; a stopped capture pauses it): an
                # upper bound for what the detector could report
                fall_clips_replayed_approx=round(plan.seconds / inp.pass_s * inp.falls_per_pass, 1))
        finally:
            for pid in stopped:
                _signal(pid, signal.SIGCONT)
            if churn is not None:
                churn.stop()
            t_term = time.monotonic()
            t_stop_unix = time.time()
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
            try:
                code = proc.wait(20)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                code = proc.wait(10)
            report["exit_status"] = code
            report["shutdown_s"] = round(time.monotonic() - t_term, 2)
            obs.close()
        time.sleep(1.0)
        left = _marked_pids(token)
        report["hooks_left_running"] = len(left)
        for pid in left:                       # the campaign's own hooks only (their argv holds the token)
            _signal(pid, signal.SIGKILL)
        report["shm_left"] = len(list(Path("/dev/shm").glob(f"posed-{proc.pid}-*")))
        if storage is not None and storage.mounted:      # the journal is read from a copy of the tmpfs
            storage.unmount(work / "state-kept")
            state = work / "state-kept"
        with obs.lock:
            received = set(obs.received)
            receipts = obs.receipts
            acked_ids = set(obs.acked_ids)
            alarm_bodies = {k: set(v) for k, v in obs.alarm_bodies.items()}
    rows = _read_journal(state / "events.sqlite3")
    logs = _log_events(out_log)
    produced = {(r.get("id"), r.get("state")) for r in logs if r.get("event") == "fall_event"}
    journaled = {(r[0], r[1]) for r in rows}
    report["events"] = {
        "produced": len(produced), "journaled": len(journaled),
        "published": sum(1 for r in rows if r[2] is not None), "received": len(received & journaled),
        "receipts": receipts, "acknowledged": sum(1 for r in rows if r[3] is not None),
        "acks_sent": len(acked_ids), "not_journaled": len(produced - journaled),
        "lost": len((produced | journaled) - received),
        "by_state": _by_state(journaled),
    }
    report["alarms"] = chaos_alarms.judge(
        chaos_alarms.read_messages(state / "events.sqlite3"), logs, kills, alarm_after_s,
        t_stop_unix if t_stop_unix is not None else time.time(), plan.alarm_grace_s, alarm_bodies)
    report["alarms"]["alarm_after_s"] = alarm_after_s
    names = [r.get("event") for r in logs]
    report["log"] = {"lines": len(logs), "ack_warnings": sum(n in ("bad_ack", "ack_of_unknown_event") for n in names),
                     "hook_lines": sum(str(n).startswith("hook") for n in names),
                     "stage_dead": sum(n == "stage_dead" for n in names),
                     "recording_problems": sum(n == "recording_problem" for n in names),
                     "frames_skipped": sum(n == "frame_skipped" for n in names),
                     "bytes": out_log.stat().st_size}
    return report


def _storage_fault(storage: chaos_faults.StorageFaults, what: str, obs, kills: list) -> None:
    """One state-directory fault; going read-only kills the publisher (it holds the journal open) if needed
    (appended to ``kills``)."""
    if what != "read_only":
        getattr(storage, what)()
        return

    def release() -> None:
        pid = ((obs.last_status() or {}).get("stages", {}).get("publisher", {})).get("pid")
        if pid and _signal(pid, signal.SIGKILL):
            kills.append((time.time(), "publisher"))
    storage.read_only(release)


def _capture_counts(status: dict | None) -> dict:
    cap = (status or {}).get("stages", {}).get("capture", {})
    return {k: cap.get(k) for k in ("frames", "skipped", "errors", "bad_frames", "drops", "restarts") if k in cap}


def _by_state(keys: set) -> dict:
    out: dict[str, int] = {}
    for _, s in keys:
        out[s] = out.get(s, 0) + 1
    return out


def run_campaign(plan: ChaosPlan, shared: Path, progress=lambda msg: None, work: Path | None = None) -> dict:
    """Every input of ``plan`` in turn; the report with a run per input and the totals."""
    t0 = time.monotonic()
    runs = []
    with tempfile.TemporaryDirectory(prefix="posed-chaos-") as tmp:
        base = Path(work or tmp)
        for i, name in enumerate(plan.inputs):
            d = base / name
            d.mkdir(parents=True, exist_ok=True)
            if name == "squat":
                inp = chaos_inputs.squat_images(shared, d / "frames", plan.corrupt_every, plan.crafted_images)
            elif name == "falls":
                inp = chaos_inputs.fall_recording(shared, d / "falls.landmarks.jsonl", plan.corrupt_every,
                                                  plan.clock_jumps)
            else:
                raise ValueError(f"unknown chaos input {name!r}; valid: squat, falls")
            runs.append(run_input(inp, plan, d, plan.seed * 100 + i, progress))
    keys = ("produced", "journaled", "published", "received", "acknowledged", "lost", "not_journaled")
    totals = {k: sum(r["events"][k] for r in runs) for k in keys}
    totals["alarm_violations"] = sum(r["alarms"]["violations"] for r in runs)
    totals["kills_mid_fall"] = sum(r["alarms"]["midfall"]["kills_mid_fall"] for r in runs)
    return {"benchmark": "chaos", "plan": asdict(plan), "machine": machine(), "runs": runs, "totals": totals,
            "seconds": round(time.monotonic() - t0, 1)}
