"""Cold start: seconds from starting ``posed run`` to its first pose on Zenoh, on a fresh install.

Protocol (issue 16; target: first pose <= 5 s after start, and READY before it):

1. a fresh, empty numba cache (``NUMBA_CACHE_DIR`` = a new temporary folder, as a fresh install's
   /var/cache/posed/numba; the fitting package's own ``__pycache__`` is not touched);
2. the install step, ``posed warmup --no-check``, timed (it compiles the fitting kernels into that cache);
3. ``--runs`` times: ``posed run`` on the real squat video (looped, real time; real landmark model, real fit)
   started as a new process group with a real sd_notify socket (``NOTIFY_SOCKET``) and joined to a Zenoh
   router this process opens on 127.0.0.1; the clock starts just before the process is spawned (what
   ``systemctl start`` does) and stops at READY=1 and at the first message on ``posed/ROBOT/pose``;
4. with ``--without-warmup`` also one run on another empty cache without step 2 (what the first start was
   before ``posed warmup``: the compile happens before READY).

The machine's load average is reported with the numbers: on a shared machine they are upper bounds. Each start
also reports the CPU seconds its processes used until the first pose (``cpu_s``: total, and the most in one
process); ``idle_bound_s`` = max(most in one process, total / CPUs) is the least wall time an idle machine of
this kind could need — a lower bound, not a measurement.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from posed.bench.notify_socket import NotifySocket

TARGET_S = 5.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--runs", type=int, default=3, help="starts after the warm-up (default 3)")
    parser.add_argument("--without-warmup", action="store_true",
                        help="also time one start on an empty cache without `posed warmup` (compiles: slow)")
    parser.add_argument("--timeout", type=float, default=300.0, metavar="S",
                        help="give up on a start after this long (default 300 s)")
    parser.add_argument("--source", metavar="URI",
                        help="input (default: the real squat video of the shared data, looped in real time)")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _router(endpoint: str):
    import zenoh

    from posed.client import session_config

    return zenoh.open(session_config("router", listen=[endpoint]))


def _children(pid: int) -> list[int]:
    out = []
    try:
        for task in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{task}/children") as fh:
                out += [int(x) for x in fh.read().split()]
    except OSError:
        pass
    return out


def _tree_cpu(pid: int) -> dict:
    """CPU seconds (user + system) used so far by ``pid`` and its descendants: on an idle machine the start
    cannot take less wall time than ``max_process`` (one process's own work) nor than ``total`` / CPUs."""
    from posed.daemon.proc.procstat import sample

    per: dict[int, float] = {}
    todo = [pid]
    while todo:
        p = todo.pop()
        s = sample(p)
        if s is not None:
            per[p] = s.cpu_s
        todo += _children(p)
    return {"total": round(sum(per.values()), 2), "max_process": round(max(per.values(), default=0.0), 2),
            "processes": len(per)}


def time_start(source: str, env: dict, work: Path, timeout_s: float, n: int) -> dict:
    """One ``posed run`` from spawn to READY=1 and to the first pose (seconds)."""
    router_ep = f"tcp/127.0.0.1:{_free_port()}"
    first: list[float] = []
    notify = NotifySocket(str(work / f"notify-{n}.sock"))
    cmd = [sys.executable, "-m", "posed.cli", "run", "--source", source,
           "--set", f"zenoh.listen=[tcp/127.0.0.1:{_free_port()}]", "--set", f"zenoh.connect=[{router_ep}]",
           "--set", f"pipeline.state_dir={work / f'state-{n}'}", "--set", "robot_id=coldstart",
           "--set", "logging.format=json"]
    log = open(work / f"run-{n}.log", "w")
    try:
        with _router(router_ep) as session:
            sub = session.declare_subscriber(
                "posed/coldstart/pose", lambda s: first.append(time.monotonic()) if not first else None)
            t0 = time.monotonic()
            proc = subprocess.Popen(cmd, env={**env, "NOTIFY_SOCKET": str(work / f"notify-{n}.sock")},
                                    stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
            try:
                while not first and proc.poll() is None and time.monotonic() - t0 < timeout_s:
                    time.sleep(0.01)
                cpu = _tree_cpu(proc.pid) if first else {}
            finally:
                proc.send_signal(signal.SIGTERM)
                try:
                    proc.wait(15)
                except subprocess.TimeoutExpired:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait()
            del sub
    finally:
        log.close()
        notify.close()
    ready = notify.ready_at
    return {"ready_s": None if ready is None else round(ready - t0, 2),
            "first_pose_s": round(first[0] - t0, 2) if first else None,
            "cpu_s": cpu,
            "ready_before_pose": bool(first and ready is not None and ready <= first[0]),
            "log": str(work / f"run-{n}.log")}


def run(args: argparse.Namespace) -> int:
    from posed.daemon.preflight import SQUAT_VIDEO, shared_data

    source = args.source
    if source is None:
        video = shared_data() / SQUAT_VIDEO
        if not video.is_file():
            print(f"posed bench coldstart: the real squat video is missing ({video}); give --source", file=sys.stderr)
            return 2
        source = f"file:{video}?loop=true"
    work = Path(tempfile.mkdtemp(prefix="posed-coldstart-"))
    root = Path(__file__).resolve().parents[2]
    base_env = {k: v for k, v in os.environ.items() if k not in ("NOTIFY_SOCKET", "WATCHDOG_USEC", "NUMBA_CACHE_DIR")}
    base_env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(root), base_env.get("PYTHONPATH")]))

    def say(msg: str) -> None:
        print(f"posed bench coldstart: {msg}", file=sys.stderr, flush=True)

    report: dict = {"benchmark": "coldstart", "target_first_pose_s": TARGET_S, "source": source,
                    "cpus": os.cpu_count(), "load_average_before": [round(x, 2) for x in os.getloadavg()]}
    try:
        cache = work / "numba-cache"
        env = {**base_env, "NUMBA_CACHE_DIR": str(cache)}
        say(f"empty numba cache {cache}; posed warmup ...")
        t0 = time.monotonic()
        w = subprocess.run([sys.executable, "-m", "posed.cli", "warmup", "--no-check"], env=env,
                           capture_output=True, text=True, timeout=1800)
        report["warmup_s"] = round(time.monotonic() - t0, 2)
        if w.returncode != 0:
            say(f"posed warmup failed: {w.stdout}{w.stderr}")
            return 1
        report["warm_runs"] = []
        for i in range(args.runs):
            say(f"start {i + 1}/{args.runs} after the warm-up ...")
            report["warm_runs"].append(time_start(source, env, work, args.timeout, i))
        if args.without_warmup:
            say("one start on an empty cache without the warm-up (compiles before READY) ...")
            cold_env = {**base_env, "NUMBA_CACHE_DIR": str(work / "numba-cache-cold")}
            report["without_warmup"] = time_start(source, cold_env, work, max(args.timeout, 600.0), 99)
        cpus = os.cpu_count() or 1
        report["idle_bound_s"] = [round(max(r["cpu_s"].get("max_process", 0.0), r["cpu_s"].get("total", 0.0) / cpus), 2)
                                  for r in report["warm_runs"] if r.get("cpu_s")]
        firsts = [r["first_pose_s"] for r in report["warm_runs"]]
        report["first_pose_s_max"] = max(firsts) if firsts and None not in firsts else None
        report["met"] = report["first_pose_s_max"] is not None and report["first_pose_s_max"] <= TARGET_S
        report["load_average_after"] = [round(x, 2) for x in os.getloadavg()]
    finally:
        shutil.rmtree(work, ignore_errors=True)
    for r in report.get("warm_runs", []) + ([report["without_warmup"]] if "without_warmup" in report else []):
        r.pop("log", None)
    if args.json:
        print(json.dumps(report))
    else:
        print(f"posed warmup (empty cache): {report['warmup_s']} s")
        for i, r in enumerate(report["warm_runs"]):
            print(f"start {i + 1}: READY after {r['ready_s']} s, first pose after {r['first_pose_s']} s; CPU until "
                  f"then {r['cpu_s'].get('total')} s in {r['cpu_s'].get('processes')} processes (most in one: "
                  f"{r['cpu_s'].get('max_process')} s)")
        if "without_warmup" in report:
            r = report["without_warmup"]
            print(f"without warm-up: READY after {r['ready_s']} s, first pose after {r['first_pose_s']} s")
        print(f"target: first pose <= {TARGET_S:g} s: {'met' if report['met'] else 'NOT met'} "
              f"(load average {report['load_average_before']} -> {report['load_average_after']} on "
              f"{report['cpus']} CPUs)")
    return 0 if report["met"] else 1
