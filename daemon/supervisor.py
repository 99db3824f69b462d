"""The supervisor: ``posed run``'s main process.

It creates the shared memory (the control segment with the health board and mailboxes, and the frame
ring), spawns the stage processes (spawn context), and then loops every 0.1 s:

* the watchdog: a dead stage, or one stuck (busy on one step too long, no heartbeat), is killed and started
  again after a backoff (:mod:`daemon.proc.watchdog`); more than ``pipeline.max_restarts`` restarts within
  ``pipeline.restart_window_s`` escalates: WATCHDOG=1 stops so systemd restarts the unit (without a systemd
  watchdog the supervisor exits with 70 instead);
* readiness: READY=1 once every stage has warmed up (models loaded, numba kernels compiled); only then may
  the capture stage start reading frames (``go``), so warm-up drops no frame of a replay;
* status every ``pipeline.status_period_s``: per-stage fps, latency, drops, restarts, CPU and memory, camera
  state -> the publisher (posed/ROBOT/status) and STATUS= for systemd; WATCHDOG=1 while every stage is healthy;
  ``state`` is starting, running, paused (for privacy: the publisher's pause, or the capture stage's camera
  closed for one; never blind then, and STATUS= says until when), waiting_for_camera (ready, but the camera
  cannot be opened or was lost: the capture stage retries), blind (the source is open but no frame reaches the landmark stage:
  :mod:`daemon.proc.blind`; ``blind`` in the status has the reason and the fix, STATUS= says it and one error
  line per ``logging.stats_period_s`` names them), degraded (a stage dead or stuck), escalated or stopping;
* a recording replayed with ``pipeline.stop_at_end`` none of whose frames was processed ends the daemon with
  exit status 65 (EX_DATAERR) and that reason, never 0;
* a stage reporting a fatal problem (a missing model or input file) stops the daemon with exit status 78; so
  does a /dev/shm without room for the shared memory, at start, before any stage runs (``shm.reserve``).

SIGTERM/SIGINT stop the stages in pipeline order (capture first: it closes the camera), kill what has not
left by ``pipeline.shutdown_timeout_s``, unlink the shared memory and return. A broken log pipe (``posed run |
tee`` and tee killed) changes nothing: logging then writes to /dev/null (:mod:`daemon.logs`); whatever fails
in the supervisor, the stages are killed before it returns, and each stage gets SIGTERM from the kernel if
the supervisor dies (``PR_SET_PDEATHSIG``).
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import sys
import time
import traceback
from dataclasses import dataclass

from posed.daemon import clock, logs
from posed.daemon.config import EX_CONFIG, Config, paths
from posed.daemon.outbox.fallback import fallback_path
from posed.daemon.proc import orphans, procstat, shm
from posed.daemon.proc.blind import BlindWatch, Counts, blind_after_s
from posed.daemon.proc.control import DOORBELLS, Control
from posed.daemon.proc.health import CAMERA_STATES
from posed.daemon.proc.notify import Notifier
from posed.daemon.proc.ring import FrameRing
from posed.daemon.proc.status import fmt_ms, memory_fields, nan_to_zero, pss_mb, rounded
from posed.daemon.proc.watchdog import RestartPolicy, verdict
from posed.daemon.stages.base import EXIT_FATAL, StageArgs, stage_main
from posed.daemon.stages.plan import StageSpec, default_plan
from posed.daemon.version import __version__
from posed.hal import is_realsense_recording, to_uri

EX_SOFTWARE = 70   # escalated without a systemd watchdog to do the restart
EX_DATAERR = 65    # a recording ended and none of its frames was processed
TICK_S = 0.1


@dataclass
class _Slot:
    spec: StageSpec
    process: multiprocessing.Process | None = None
    restart_at: float | None = None
    restarts: int = 0
    last_reason: str = ""


class Supervisor:
    """Run the pipeline until stopped; :meth:`run` returns the exit status."""

    def __init__(self, config: Config, plan: tuple[StageSpec, ...] | None = None,
                 notifier: Notifier | None = None) -> None:
        self.config = config
        self.plan = plan or default_plan(config)
        self.notifier = notifier or Notifier()
        self.log = logs.get("supervisor", pid=os.getpid())
        p = config.pipeline
        self.policy = RestartPolicy(p.max_restarts, p.restart_window_s, backoff_max_s=p.backoff_max_s)
        self._ctx = multiprocessing.get_context("spawn")
        self._slots = {s.name: _Slot(s) for s in self.plan}
        self._stop_reason = ""
        self._exit_code = 0
        self._ready_sent = False
        self._escalated = False
        self._camera_info: dict = {}
        self._cpu = procstat.CpuMeter()
        self._t0 = clock.now()
        self._next_status = 0.0
        self._next_stats_log = 0.0
        self._next_ping = 0.0
        self._ended_at: float | None = None
        self._consumer = next((s.name for s in self.plan if s.input and any(
            c.name == "capture" and c.output == s.input for c in self.plan)), None)
        self._blind = BlindWatch(self._consumer or "landmarks", blind_after_s(config.pipeline.target_fps))
        self._problem: dict | None = None        # the capture stage's last reported problem {error, fix}
        self._conflict: dict | None = None       # the publisher's zenoh.robot_id_conflict: our robot id used twice
        self._privacy: dict = {}                 # the publisher's pause for privacy (PrivacyKeeper.status)
        self._presence: dict | None = None       # the publisher's presence (PresenceWatch.state): absent or not
        self.models = models_in_use(config)      # the status's "models": read once, from the manifest
        self.time_zone = robot_zone()            # the status's "time_zone": the zone people read times in
        self._next_blind_log = 0.0
        self.control: Control | None = None
        self.ring: FrameRing | None = None
        self._sem_record = None
        self.last_status: dict = {}

    # ------------------------------------------------------------------ public
    def request_stop(self, reason: str) -> None:
        if not self._stop_reason:
            self._stop_reason = reason

    def run(self) -> int:
        previous = {sig: signal.signal(sig, self._on_signal) for sig in (signal.SIGTERM, signal.SIGINT)}
        try:
            self._start()
            while not self._stop_reason:
                self._tick(clock.now())
                time.sleep(TICK_S)
        except Exception as exc:  # a bug in the supervisor itself: stop cleanly, let systemd restart us
            self._exit_code = EX_SOFTWARE
            self.request_stop("supervisor error")
            with contextlib.suppress(Exception):
                self.log.error("supervisor_failed", error=repr(exc), traceback=traceback.format_exc(limit=8))
        finally:
            try:
                self._shutdown()
            finally:                  # whatever failed above: no stage outlives the supervisor
                self._kill_remaining()
                for sig, handler in previous.items():
                    signal.signal(sig, handler)
        return self._exit_code

    def _kill_remaining(self) -> None:
        for slot in self._slots.values():
            if slot.process is not None and slot.process.is_alive():
                _kill(slot.process)
        self._end_orphans(orphans.of_supervisor(os.getpid()), "the daemon stopped")

    def _end_orphans(self, pids: list[int], why: str) -> None:
        """End hook processes a stage left behind (they run in sessions of their own)."""
        if pids:
            orphans.end(pids)
            self.log.warning("hooks_left_behind_ended", pids=pids[:20], count=len(pids), why=why)

    # ------------------------------------------------------------------ start
    def _start(self) -> None:
        self._end_orphans(orphans.of_dead_supervisors(), "left by a posed daemon that was killed")
        stale = shm.remove_stale()
        if stale:
            self.log.warning("removed_stale_shared_memory", segments=stale,
                             note="left by a posed supervisor that was killed")
        names = tuple(s.name for s in self.plan)
        try:
            self._create_shared_memory(names)
        except shm.SharedMemoryFull as exc:       # /dev/shm full: said now, not a SIGBUS of a stage later
            self._shm_full(exc)
            return
        self.log.info("daemon_start", robot=self.config.robot_id, stages=list(names),
                      source=to_uri(self.config.source), watchdog_s=self.notifier.watchdog_interval_s)
        now = clock.now()
        for slot in self._slots.values():
            self._spawn(slot, now)

    def _create_shared_memory(self, names: tuple[str, ...]) -> None:
        """The doorbells, the control segment and the frame ring, every page reserved (shm.create);
        :class:`shm.SharedMemoryFull` when /dev/shm has not room for them."""
        page = os.sysconf("SC_PAGE_SIZE")
        with shm.no_room_is_full("a doorbell semaphore", page):     # sem_open writes a page into /dev/shm
            doorbells = {name: self._ctx.Semaphore(0) for name in DOORBELLS}
        self._doorbells = doorbells
        sem_names = [n for n in (getattr(d._semlock, "name", None) for d in doorbells.values()) if n]
        with shm.no_room_is_full("the list of doorbell semaphores", page):
            self._sem_record = shm.record_semaphores(sem_names)    # removed at the next start if we are killed
        self.control = Control.create(names, doorbells)
        if any(s.uses_ring for s in self.plan):
            src = self.config.source
            capacity = self.config.pipeline.frame_max_pixels   # larger frames are scaled down at capture
            depth = src.type == "realsense" or is_realsense_recording(src.path)
            self.ring = FrameRing.create(self.config.pipeline.ring_slots, capacity, depth)

    def _shm_full(self, exc: shm.SharedMemoryFull) -> None:
        """Stop before any stage starts, as a start-up problem: exit status 78, the problem and its fix."""
        self.log.error("shared_memory_full", error=exc.message, needed_bytes=exc.needed, free_bytes=exc.free,
                       fix=exc.fix)
        with contextlib.suppress(OSError):
            print(f"posed: {exc.message}\n  fix: {exc.fix}\nposed: 1 problem(s); nothing was started",
                  flush=True, file=sys.stderr)
        self._exit_code = EX_CONFIG
        self.request_stop("/dev/shm is full")

    def _spawn(self, slot: _Slot, now: float) -> None:
        spec = slot.spec
        self.control.board.reset(spec.name, now)
        if self._ready_sent:
            self.control.board.row(spec.name).set("go", 1.0)
        args = StageArgs(name=spec.name, entry=spec.entry, config=self.config, control=self.control.spec,
                         ring=self.ring.spec if (spec.uses_ring and self.ring) else None,
                         supervisor_pid=os.getpid(), input=spec.input, output=spec.output)
        proc = self._ctx.Process(target=stage_main, args=(args, self._doorbells), name=f"posed-{spec.name}")
        proc.start()
        slot.process = proc
        slot.restart_at = None
        if spec.name == "publisher":
            self._conflict = None       # a new publisher's session says it again while it lasts
            self._presence = None       # ... and a new publisher's presence judges the absence afresh
        self.control.board.row(spec.name).set("pid", proc.pid)

    # ------------------------------------------------------------------ the loop
    def _tick(self, now: float) -> None:
        self._read_reports()
        if self._stop_reason:
            return
        self._watch(now)
        if self._stop_reason:
            return
        if not self._ready_sent and self._all_ready():
            self._ready_sent = True
            for slot in self._slots.values():
                self.control.board.row(slot.spec.name).set("go", 1.0)
            self.notifier.ready(status_text(self.status(now), self._conflict, self._presence)
                                + f"; warm-up took {now - self._t0:.1f} s")
            self.log.info("daemon_ready", warmup_s=round(now - self._t0, 2))
        if now >= self._next_status:
            self._next_status = now + self.config.pipeline.status_period_s
            self._publish_status(now)
        self._maybe_ping(now)
        self._watch_blind(now)
        self._check_end(now)

    def _read_reports(self) -> None:
        for slot in self._slots.values():
            info = self.control.mailbox(f"report.{slot.spec.name}").take()
            if not info:
                continue
            if "camera" in info:
                self._camera_info = dict(info["camera"])
            if "problem" in info:
                self._problem = dict(info["problem"])
            if "robot_id_conflict" in info:
                self._conflict = info["robot_id_conflict"]
            if "privacy" in info:
                self._privacy = dict(info["privacy"] or {})
            if "presence" in info:
                self._presence = info["presence"]
            if "fatal" in info:
                self._fatal(slot.spec.name, info["fatal"], info.get("fix", ""))

    def _fatal(self, stage: str, message: str, fix: str) -> None:
        self.log.error("daemon_fatal", stage=stage, error=message, fix=fix)
        with contextlib.suppress(OSError):           # a closed or broken stderr must not stop the stop
            print(f"posed: {stage}: {message}" + (f"\n  fix: {fix}" if fix else ""), flush=True, file=sys.stderr)
        self._exit_code = EX_CONFIG
        self.request_stop(f"fatal problem in {stage}")

    def _watch(self, now: float) -> None:
        p = self.config.pipeline
        for slot in self._slots.values():
            name = slot.spec.name
            if slot.restart_at is not None:
                if now >= slot.restart_at:
                    self._spawn(slot, now)
                    self.log.info("stage_restarted", stage=name, stage_pid=slot.process.pid, restarts=slot.restarts,
                                  reason=slot.last_reason)
                continue
            proc = slot.process
            row = self.control.board.row(name)
            alive = proc.is_alive()
            if not alive and proc.exitcode == EXIT_FATAL:
                self._read_reports()
                if not self._stop_reason:
                    self._fatal(name, "the stage stopped with a problem restarting cannot fix; see its log",
                                "")
                return
            v = verdict(alive, proc.exitcode, row.state, row.get("beat"), row.get("step_started"),
                        row.get("started"), now, p.stuck_after_s, p.startup_timeout_s)
            if v.kind == "ok":
                continue
            if alive:
                _kill(proc)
            self._end_orphans(orphans.of_stage(os.getpid(), proc.pid), f"the {name} stage died")
            slot.restarts += 1
            slot.last_reason = f"{v.kind}: {v.reason}"
            delay = self.policy.delay(name, now)
            self.policy.record(name, now)
            slot.restart_at = now + delay
            self.log.warning("stage_" + v.kind, stage=name, reason=v.reason, restart_in_s=round(delay, 2),
                             restarts_in_window=self.policy.recent(now))
            if self.policy.escalated(now) and not self._escalated:
                self._escalate(now)

    def _escalate(self, now: float) -> None:
        self._escalated = True
        p = self.config.pipeline
        message = (f"{self.policy.recent(now)} restarts within {p.restart_window_s:g} s "
                   f"(pipeline.max_restarts = {p.max_restarts})")
        if self.notifier.watchdog_interval_s is not None:
            self.log.error("daemon_escalated", reason=message,
                           action="WATCHDOG=1 stopped: systemd will restart the unit")
            self.notifier.status(f"escalated: {message}")
        else:
            self.log.error("daemon_escalated", reason=message,
                           action=f"no systemd watchdog: exiting with {EX_SOFTWARE} so the service manager "
                                  "restarts the daemon")
            self._exit_code = EX_SOFTWARE
            self.request_stop("escalated")

    def _all_ready(self) -> bool:
        for slot in self._slots.values():
            row = self.control.board.row(slot.spec.name)
            if slot.restart_at is not None or row.get("ready") < 1 or row.state != "running":
                return False
        return True

    def healthy(self) -> bool:
        """Every stage alive and not stuck, and no escalation: the condition for WATCHDOG=1."""
        if self._escalated:
            return False
        p = self.config.pipeline
        now = clock.now()
        for slot in self._slots.values():
            if slot.restart_at is not None or slot.process is None:
                return False
            row = self.control.board.row(slot.spec.name)
            v = verdict(slot.process.is_alive(), slot.process.exitcode, row.state, row.get("beat"),
                        row.get("step_started"), row.get("started"), now, p.stuck_after_s, p.startup_timeout_s)
            if v.kind != "ok":
                return False
        return True

    def _maybe_ping(self, now: float) -> None:
        interval = self.notifier.watchdog_interval_s
        if interval is None or now < self._next_ping or not self._ready_sent:
            return                       # systemd arms the watchdog once start-up is complete (READY=1)
        if self.healthy():
            self.notifier.watchdog()
            self._next_ping = now + interval

    def _check_end(self, now: float) -> None:
        if not self.config.pipeline.stop_at_end:
            return
        cap = self.control.board.row("capture")
        if cap.camera != "ended":
            self._ended_at = None
            return
        if self._ended_at is None:
            self._ended_at = now
        busy = any(self.control.mailbox(s.input).pending() for s in self.plan if s.input)
        if not busy and now - self._ended_at > 1.0:
            if self._consumer is not None and not self._blind.processed_any:
                self._never_processed(now)
                return
            self.request_stop("the recording ended (pipeline.stop_at_end)")

    def _never_processed(self, now: float) -> None:
        """A recording ended with none of its frames processed: say why and exit EX_DATAERR, never 0."""
        blind = self._blind.update(now, True, "ended", self._counts(), self._problem) or {
            "reason": "the recording ended and none of its frames was processed", "fix": ""}
        self.log.error("recording_not_processed", reason=blind["reason"], fix=blind["fix"])
        with contextlib.suppress(OSError):
            print(f"posed: {blind['reason']}" + (f"\n  fix: {blind['fix']}" if blind["fix"] else ""), flush=True,
                  file=sys.stderr)
        self._exit_code = EX_DATAERR
        self.request_stop("the recording ended and none of its frames was processed")

    # ------------------------------------------------------------------ blind
    def _counts(self) -> Counts:
        cap = self.control.board.row("capture") if "capture" in self._slots else None
        con = self.control.board.row(self._consumer) if self._consumer else None
        if cap is None or con is None:
            return Counts()
        return Counts(captured=int(cap.get("frames")), bad_frames=int(cap.get("bad_frames")),
                      timeouts=int(cap.get("errors")), processed=int(con.get("frames")),
                      consumer_errors=int(con.get("errors")))

    def _watch_blind(self, now: float) -> None:
        if self._consumer is None:
            return
        was = self._blind.blind
        camera = "paused" if self.paused() else self.control.board.row("capture").camera
        blind = self._blind.update(now, self._ready_sent, camera, self._counts(), self._problem)
        if blind is not None and (was is None or now >= self._next_blind_log):
            self._next_blind_log = now + self.config.logging.stats_period_s
            self.log.error("blind", reason=blind["reason"], fix=blind["fix"], since_s=blind["since_s"],
                           source=to_uri(self.config.source))
        elif blind is None and was is not None:
            self.log.info("blind_ended", note="frames reach the landmark stage again")

    # ------------------------------------------------------------------ status
    def paused(self) -> bool:
        """Paused for privacy: the publisher says a pause runs (and its end has not passed), or the capture stage
        has closed the camera for one. Never blind then, and the state says ``paused``."""
        p = self._privacy
        if p.get("paused") and float(p.get("until_unix") or 0.0) > time.time():
            return True
        return "capture" in self._slots and self.control.board.row("capture").camera == "paused"

    def _privacy_field(self) -> dict:
        """The status's ``privacy`` as the supervisor knows it (the publisher's own status refreshes it)."""
        out = dict(self._privacy) or {"allow_pause": self.config.privacy.allow_pause,
                                      "max_pause_s": float(self.config.privacy.max_pause_s), "paused": False}
        if out.get("paused") and out.get("until_unix") is not None:
            out["remaining_s"] = round(max(0.0, float(out["until_unix"]) - time.time()), 1)
        return out

    def _publish_status(self, now: float) -> None:
        status = self.status(now)
        self.last_status = status
        try:
            self.control.mailbox("status").put(status)
        except ValueError as exc:
            self.log.error("status_too_large", error=str(exc))
        self.notifier.status(status_text(status, self._conflict, self._presence))
        e2e = status["latency_ms"]
        if now >= self._next_stats_log:
            self._next_stats_log = now + self.config.logging.stats_period_s
            self.log.info("stats", fps=status["fps"], latency_ms=e2e, drops=status["drops"],
                          restarts=status["restarts"], memory_mb=status["memory_mb"], state=status["state"])

    def status(self, now: float) -> dict:
        """The status object (posed/ROBOT/status) as the supervisor sees it."""
        stages = {}
        total_pss = total_anon = 0.0
        total_drops = 0
        own = procstat.sample(os.getpid())
        if own is not None:
            total_pss += pss_mb(own)
            total_anon += nan_to_zero(own.anon_mb)
        for slot in self._slots.values():
            name = slot.spec.name
            r = self.control.board.row(name).snapshot()
            proc = slot.process
            alive = proc is not None and proc.is_alive() and slot.restart_at is None
            entry = {
                "pid": proc.pid if proc else None, "alive": alive,
                "state": "restarting" if slot.restart_at is not None else self.control.board.row(name).state,
                "fps": rounded(r["fps"], 2), "frames": int(r["frames"]), "drops": int(r["drops"]),
                "skipped": int(r["skipped"]), "errors": int(r["errors"]), "bad_frames": int(r["bad_frames"]),
                "restarts": slot.restarts,
                "step_ms": {"p50": rounded(r["step_p50_ms"]), "p95": rounded(r["step_p95_ms"]),
                            "max": rounded(r["step_max_ms"])},
                "latency_ms": {"p50": rounded(r["lat_p50_ms"]), "p95": rounded(r["lat_p95_ms"]),
                               "max": rounded(r["lat_max_ms"])},
            }
            if name == "web":
                entry["bus_connected"] = not r["bus_down"]
            total_drops += int(r["drops"])
            if alive:
                s = procstat.sample(proc.pid)
                if s is not None:
                    entry.update(memory_fields(s, self._cpu.percent(s, now)))
                    total_pss += pss_mb(s)
                    total_anon += nan_to_zero(s.anon_mb)
            stages[name] = entry
        sup = {"pid": os.getpid()}
        if own is not None:
            sup.update(memory_fields(own, self._cpu.percent(own, now)))
        pub = stages.get("publisher", {})
        cap_row = self.control.board.row("capture") if "capture" in self._slots else None
        if self._stop_reason:
            state = "stopping"
        elif self._escalated:
            state = "escalated"
        elif not self._ready_sent:
            state = "starting"
        elif not self.healthy():
            state = "degraded"
        elif self.paused():
            state = "paused"                    # for privacy: not watching on purpose, until it ends
        elif cap_row is not None and cap_row.camera in ("lost", "opening"):
            state = "waiting_for_camera"        # ready, but no camera to read (unplugged, wrong device)
        elif self._blind.blind is not None:
            state = "blind"                     # the source is open, but no frame gets through
        else:
            state = "running"
        return {
            "robot": self.config.robot_id,
            "posed_version": __version__,      # "version" is the message format's (daemon.bus.payloads)
            "models": self.models,             # which landmark models run (as `posed --version`'s second line)
            "time_zone": self.time_zone,       # the robot's IANA zone (daemon.timeparse.local_zone), or null
            "time": clock.iso(time.time()),
            "uptime_s": round(now - self._t0, 1),
            "state": state,
            "ready": self._ready_sent,
            "fps": pub.get("fps") or 0.0,
            "latency_ms": pub.get("latency_ms", {"p50": None, "p95": None, "max": None}),
            "drops": total_drops,
            "restarts": self.policy.total,
            "camera": {**self._camera_info, "state": cap_row.camera if cap_row else CAMERA_STATES[0],
                       "source": to_uri(self.config.source)},
            "blind": None if state == "paused" else self._blind.blind,
            "privacy": self._privacy_field(),
            "storage": self._storage(),
            "stages": stages,
            "supervisor": sup,
            "memory_mb": round(total_pss, 1),
            "anon_mb": round(total_anon, 1),
            "processes": 1 + sum(1 for s in stages.values() if s["alive"]),
        }

    def _storage(self) -> dict:
        """The state directory as the publisher last reported it in its health row (the publisher's own status
        adds the reason and the fix)."""
        unstored = fault = 0
        if self.control is not None and "publisher" in self._slots:
            row = self.control.board.row("publisher")
            unstored, fault = int(row.get("unstored")), int(row.get("storage_fault"))
        return {"state": "degraded" if fault or unstored else "ok", "unstored_events": unstored,
                "fallback": str(fallback_path(paths.state_dir(self.config.pipeline)))}

    def _report_unstored(self) -> None:
        """At stop: fall-event messages that never reached the disk are said loudly, with where they are."""
        st = self._storage()
        if not st["unstored_events"]:
            return
        text = (f"{st['unstored_events']} fall-event messages were never written to disk (the state directory "
                f"{paths.state_dir(self.config.pipeline)} failed); they are in {st['fallback']}, taken back at "
                "the next start, which survives a restart of posed but not a reboot")
        self.log.error("events_not_stored", unstored_events=st["unstored_events"], fallback=st["fallback"],
                       fix="free disk space or make pipeline.state_dir writable, then start posed again")
        with contextlib.suppress(OSError):
            print(f"posed: {text}", file=sys.stderr, flush=True)

    # ------------------------------------------------------------------ stop
    def _on_signal(self, signum, frame) -> None:
        self.request_stop(signal.Signals(signum).name)

    def _shutdown(self) -> None:
        t_start = clock.now()
        deadline = t_start + self.config.pipeline.shutdown_timeout_s
        self.notifier.stopping(f"stopping: {self._stop_reason or 'error'}")
        self.log.info("daemon_stopping", reason=self._stop_reason or "error")
        if self.control is not None:
            for slot in self._slots.values():          # pipeline order: capture first (closes the camera)
                proc = slot.process
                if proc is None or not proc.is_alive():
                    continue
                self.control.board.row(slot.spec.name).set("stop", 1.0)
                share = max(0.2, (deadline - clock.now()) / 2)
                proc.join(min(share, max(0.0, deadline - clock.now())))
            for slot in self._slots.values():
                proc = slot.process
                if proc is not None and proc.is_alive():
                    proc.join(max(0.0, deadline - clock.now()))
                if proc is not None and proc.is_alive():
                    self.log.warning("stage_killed_at_shutdown", stage=slot.spec.name, stage_pid=proc.pid)
                    _kill(proc)
        if self.ring is not None:
            self.ring.close()
            self.ring = None
        self._report_unstored()
        if self.control is not None:
            self.control.close()
            self.control = None
        if self._sem_record is not None:
            with contextlib.suppress(OSError):
                self._sem_record.unlink()
        self.log.info("daemon_stopped", seconds=round(clock.now() - t_start, 2), exit_code=self._exit_code)


def robot_zone() -> str | None:
    """This machine's (the robot's) IANA time zone by ``daemon.timeparse.local_zone``'s rule (``$TZ``, else
    /etc/localtime), which every command shows times in; None when only a fixed offset is known. Read once at
    start: a zone changed with timedatectl takes a restart, as for every other process."""
    from posed.daemon.timeparse import local_zone

    return getattr(local_zone(), "key", None)


def models_in_use(config: Config) -> dict:
    """The landmark models the daemon runs, from the models folder's manifest (``landmarks.installed_models``:
    dir, converter_version, mediapipe, the two ONNX sha256, or dir and error); never raises."""
    from posed.landmarks import installed_models

    try:
        return installed_models(config.landmarks.models_dir or None)
    except Exception as exc:        # an unreadable folder must not stop the daemon: the status says why
        return {"dir": str(config.landmarks.models_dir or ""), "error": f"cannot read the models folder: {exc}"}


def status_text(status: dict, conflict: dict | None = None, presence: dict | None = None) -> str:
    """systemd's STATUS= line for a status object: the state first, then what matters for it; ``conflict``: the
    publisher's ``zenoh.robot_id_conflict`` (another daemon uses our robot id), said at the end; ``presence``:
    the publisher's (the status's ``presence``), said while the person is not seen for longer than usual."""
    return _state_text(status) + absence_text(presence) + conflict_text(conflict)


def absence_text(presence: dict | None) -> str:
    """``; PERSON NOT SEEN FOR 3 h 10 min — longer than on any of the last 14 days (usually back within 2 h
    5 min)`` while the presence says ``absent`` (hooks.on_absent's rule, daemon.history.absence); "" otherwise.
    The words are the client's (client.absence_note), as ``posed watch`` says them."""
    from posed.client import Presence, absence_note

    note = absence_note(Presence.from_json(presence))
    return f"; {note}" if note else ""


def conflict_text(conflict: dict | None) -> str:
    """``; ROBOT ID IN USE TWICE (pid 12 on host nuc1 (Zenoh id ...)): give each ...`` while another daemon on
    the network uses this robot id (its log's ``robot_id_in_use`` has the whole fix); "" when none."""
    if not conflict:
        return ""
    others = "; ".join(str(o) for o in conflict.get("other_daemons") or ()) or "another posed daemon"
    return f"; ROBOT ID IN USE TWICE ({others}): give each posed daemon on one Zenoh network its own robot_id"


def paused_text(privacy: dict) -> str:
    """``PAUSED for privacy until 15:42 (by voice)``: the end in the robot's local time (daemon.timeparse)."""
    from posed.daemon.timeparse import local_zone, until_text

    until = privacy.get("until_unix")
    when = until_text(float(until), local_zone(), zone=False) if until is not None else "?"
    by = privacy.get("by")
    return f"PAUSED for privacy until {when}" + (f" (by {by})" if by else "")


def _state_text(status: dict) -> str:
    from posed.client import dark_note

    cam = status["camera"]
    if status["state"] == "paused":
        return f"{paused_text(status.get('privacy') or {})}; restarts {status['restarts']}"
    if status["state"] == "waiting_for_camera":
        error = f": {cam['error']}" if cam.get("error") else ""
        return (f"waiting_for_camera: {cam['source']} is not available{error}; retrying, restarts "
                f"{status['restarts']}")
    what = "recording" if cam.get("kind") == "file" or str(cam.get("source") or "").startswith("file:") else "camera"
    if status["state"] == "blind" and status.get("blind"):
        return (f"blind: {status['blind']['reason']}; fix: {status['blind']['fix']}; {what} {cam['state']}, "
                f"restarts {status['restarts']}")
    e2e = status["latency_ms"]
    text = (f"{status['state']}: {status['fps']:.1f} fps, latency p95 {fmt_ms(e2e['p95'])} ms, drops "
            f"{status['drops']}, restarts {status['restarts']}, {what} {cam['state']}{dark_note(cam)}")
    storage = status.get("storage") or {}
    if storage.get("state", "ok") != "ok":
        text += (f"; STORAGE DEGRADED: the state directory fails, {storage.get('unstored_events', 0)} fall-event "
                 f"messages not on disk (kept in memory and {storage.get('fallback')})")
    return text


def _kill(proc: multiprocessing.Process) -> None:
    try:
        os.kill(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.join(2.0)
