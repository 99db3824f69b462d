"""Publisher stage: fall detection, and everything that leaves the pipeline (interfaces.md section 4).

Per fit result (``fits`` mailbox), in this order:

1. the bus (:class:`daemon.bus.link.BusLink`): ``posed/ROBOT/pose`` (the fit result JSON plus ``time_unix``,
   ``image_size`` and ``timing_ms``; congestion control DROP, never blocks the pipeline) and
   ``posed/ROBOT/landmarks`` (the frame object of interfaces.md section 1 plus ``image_size``);
2. **fall detection** (:class:`daemon.stages.fall_watch.FallWatch`: the :mod:`falls` detector on every frame,
   on capture timestamps);
3. each fall-event message to the outbox (:class:`daemon.outbox.delivery.EventOutbox`): into the journal
   *before* it is published on ``posed/ROBOT/events/fall`` (reliable, congestion control BLOCK, never
   dropped), then to the hooks;
4. the joint angles to the history (:class:`daemon.history.recorder.HistoryRecorder`) and to ROS 2: the frame's
   own person's, or with ``falls.household`` the member's recognised in view (``FallWatch.followed``).

Fall alarms kept (docs/falls.md, "The alarm across a restart" and "The alarm without frames"): at the start, the
falls the journal holds open (no ``alarm``, no ``recovered``) are taken back with their ids and alarm times
(:class:`daemon.stages.restored_falls.RestoredFalls`); between frames their alarms are raised when due, and
when no frame has been processed for the blind threshold (:func:`daemon.proc.blind.blind_after_s`, the
supervisor's: 3 s at any usual frame rate) the detectors' alarm timers run on without frames
(:meth:`FallWatch.tick`).

Between frames: ``posed/ROBOT/status`` (the supervisor's status every ``pipeline.status_period_s``, plus the
Zenoh session, the event backlog and ``watch``: whether posed is watching, since when and why not, the rule of
``hooks.on_watch_lost``; and ``presence``: when the person was last seen and whether that is longer ago than
usual, the rule of ``hooks.on_absent``, :mod:`daemon.history.absence`); unacknowledged events published again
when a new subscriber to events/fall appears and every ``zenoh.event_republish_s``; history maintenance. The
bus also holds the liveliness token ``posed/ROBOT/alive``, the queryables ``posed/ROBOT/state`` (latest pose +
status) and ``posed/ROBOT/events/history`` (stored events; parameters ``since``, ``until`` (unix seconds or ISO 8601),
``limit``), and the subscriber ``posed/ROBOT/events/ack``: a receiver puts an event id there (text, or JSON
``{"id": ...}``) to acknowledge every message of that event so far, or ``{"id": ..., "state": ...}`` for only
that state's message (:mod:`daemon.bus.acks`). With ``falls.camera_mount_from_bus``, the subscriber
``posed/ROBOT/camera/mount``: the camera's pose from the robot (:class:`daemon.stages.mount_feed.MountFeed`),
given to the fall detector for the frames it covers and passed on to the fitting stage (the ``mount`` mailbox).

Paused for privacy (``posed/ROBOT/privacy/pause``, :class:`daemon.stages.privacy_keeper.PrivacyKeeper`): the
queryable is answered here, the pause kept in privacy.json and handed to the capture stage (the ``privacy``
mailbox) and to the supervisor (its report mailbox); a frame that arrives meanwhile is dropped (no pose, history
or event), the state reply's pose is null, the status says ``paused`` and ``privacy``; the fall detector starts
afresh when watching resumes.

The session is opened here, after spawn, inside ``with``; when it cannot be opened (client mode without a
router, a busy port) the stage keeps consuming frames, journals events and retries every
``zenoh.reconnect_s``.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import replace
from pathlib import Path

from posed.daemon import clock
from posed.daemon.bus.link import BusLink
from posed.daemon.bus.payloads import (
    event_message,
    landmarks_message,
    pose_message,
    stamp_event,
    status_message,
)
from posed.daemon.bus.ros2 import Ros2Bridge
from posed.daemon.bus.session import ZenohConfigError
from posed.daemon.config import paths
from posed.daemon.history.absence import AbsenceNotice, PresenceWatch
from posed.daemon.history.recorder import HistoryRecorder
from posed.daemon.history.store import AngleHistory
from posed.daemon.messages import FitMsg, origin
from posed.daemon.outbox.delivery import EventOutbox
from posed.daemon.outbox.fallback import FallbackStore, fallback_path
from posed.daemon.outbox.hooks import HookRunner
from posed.daemon.outbox.journal import EventJournal
from posed.daemon.outbox.private import private_file, private_folder
from posed.daemon.outbox.watch_hooks import WatchHooks, WatchLoss
from posed.daemon.proc import orphans
from posed.daemon.proc.blind import blind_after_s
from posed.daemon.stages.base import StageRuntime
from posed.daemon.stages.fall_watch import FallWatch, geometry_file
from posed.daemon.stages.mount_feed import MountFeed
from posed.daemon.stages.privacy_keeper import PrivacyKeeper
from posed.daemon.stages.restored_falls import RestoredFalls

WATCHING_STATES = ("running", "blind", "waiting_for_camera")     # what a pause for privacy is said over


class PublisherStage:
    """The parts the stage composes; ``handle`` per fit, ``periodic`` between them (monotonic seconds)."""

    privacy: PrivacyKeeper | None = None     # the pause for privacy (set in __init__)

    @property
    def paused(self) -> bool:
        """Paused for privacy now."""
        return self.privacy is not None and self.privacy.paused

    def __init__(self, rt: StageRuntime, stack: contextlib.ExitStack) -> None:
        self.rt = rt
        cfg = rt.config
        self.falls = FallWatch.from_config(cfg.falls, cfg.robot_id, rt.log, on_error=rt.error,
                                           state_file=geometry_file(paths.state_dir(cfg.pipeline), cfg.source))
        # the camera's pose from the robot (falls.camera_mount_from_bus): to the detector and the fitting stage
        self.mount = MountFeed(rt.log, rt.mailbox("mount")) if cfg.falls.camera_mount_from_bus else None
        if self.mount is not None:
            self.falls.mount = self.mount
        self.bus = BusLink(cfg.zenoh, cfg.robot_id, stack, rt.log,
                           history=self._stored_events, on_ack=self._acknowledge,
                           on_mount=self.mount.on_payload if self.mount is not None else None,
                           on_pause=self._ask_pause)
        private_folder(paths.state_dir(cfg.pipeline), rt.log)         # health data: 0700, files 0600
        if cfg.falls.history_enabled:
            private_file(paths.history_path(cfg.pipeline))
        journal = EventJournal(paths.events_path(cfg.pipeline),
                               fallback=FallbackStore(fallback_path(paths.state_dir(cfg.pipeline))))
        self.outbox = EventOutbox(journal, HookRunner(cfg.hooks), self._send_event, rt.log,
                                  cfg.zenoh.event_republish_s)
        # falls left open by the run before (killed between on_floor and alarm): their alarms are kept
        self.restored = RestoredFalls.load(journal, cfg.falls, rt.log)
        # no frame for this long (the supervisor's blind threshold): the alarm timers run on without frames
        self.tick_after_s = blind_after_s(cfg.pipeline.target_fps)
        self._frame_at = clock.now()          # when the last frame was handled (monotonic; at first: the start)
        self._frame_t: float | None = None    # ... and its capture time
        self.ros2 = Ros2Bridge(cfg.ros2, rt.log) if cfg.ros2.enabled else None    # docs/ros2.md
        # posed not watching (camera lost, blind, ended; a stage failing) said to the hooks that want it
        self.watch = WatchLoss(cfg.robot_id, cfg.hooks.watch_lost_after_s)
        self.watch_hooks = WatchHooks(cfg.hooks, rt.log) if cfg.hooks.on_watch_lost else None
        # what a hook leaves behind (setsid) comes back here; no hooks configured: nothing to adopt or scan for
        self.subreaper = bool(cfg.hooks.on_event or cfg.hooks.on_watch_lost or cfg.hooks.on_absent) \
            and orphans.become_subreaper()
        self._next_reap = 0.0
        self._stack = stack
        self._conflict_said: list | None = None     # the other daemons with our robot id told the supervisor
        self._conflict_state: dict | None = None    # ... and the conflict itself, as last told
        self.history = HistoryRecorder(
            AngleHistory(paths.history_path(cfg.pipeline), cfg.falls) if cfg.falls.history_enabled else None,
            rt.log, presence=_presence_watch(cfg, rt.log))
        # the person not seen for longer than usual (daemon.history.absence) said to the hooks that want it
        self.absent_hooks = (WatchHooks(cfg.hooks, rt.log, cfg.hooks.on_absent, key="on_absent",
                                        log_as="absent_hook", field="absence")
                             if cfg.hooks.on_absent and self.history.presence is not None else None)
        self._told_presence: tuple | None = None    # what the supervisor was last told of an absence
        # paused for privacy (posed/ROBOT/privacy/pause): kept in the state dir, handed to the capture stage
        self.privacy = PrivacyKeeper(cfg.privacy, cfg.robot_id, paths.state_dir(cfg.pipeline), rt.log,
                                     mailbox=rt.mailbox("privacy"), pause_log=_pause_log(cfg, rt.log),
                                     open_fall=self._open_fall)
        self._was_paused = self.privacy.paused
        self._told_pause = self.privacy.pause       # what the supervisor was last told
        self._report()

    def try_open(self, now: float) -> None:
        """Open the session when it is closed and the retry time has come; then send what waited."""
        try:
            opened = self.bus.try_open(now)
        except ZenohConfigError as exc:
            self.rt.fatal(str(exc), fix=getattr(exc, "fix", "fix zenoh.config_file"))  # ListenPortTaken: its own
        if opened:
            if self.ros2 is not None:
                self.ros2.open(self.bus.session, self._stack)
            self.outbox.session_opened()

    def handle(self, msg: FitMsg) -> None:
        if self.paused:             # a frame still in the pipeline when the pause began: never published
            return
        pose = pose_message(msg, clock.now(), self.rt.config.robot_id)
        self.bus.put_pose(pose)
        poses = {id(msg.result): pose}
        for other in msg.others:        # several people: one pose object per person, the frame's seq
            poses[id(other)] = pose_message(replace(msg, result=other, others=()), clock.now(),
                                            self.rt.config.robot_id)
            self.bus.put_pose(poses[id(other)])
        if self.bus.wants_landmarks:
            self.bus.put_landmarks(landmarks_message(msg, self.rt.config.robot_id))
        events = self.falls.update(msg)
        self._frame_at, self._frame_t = clock.now(), float(msg.result.t)
        for event in self.restored.frame(msg, self.falls, events, self._frame_at):
            self.outbox.post(stamp_event(event))    # unix times before the journal
        followed = self.falls.followed(msg)       # the household member's, when one is known: else the frame's
        if self.ros2 is not None:                 # ROS 2's one JointState stream follows that person too
            self.ros2.publish_pose(poses.get(id(followed)) or pose_message(replace(msg, result=followed, others=()),
                                                                           clock.now(), self.rt.config.robot_id))
        self.history.add(followed, msg.t_capture)
        self.absence_notices()

    def periodic(self, now: float) -> None:
        status = self.rt.mailbox("status").take()
        if status is not None:
            self.publish_status(status)
        self.bus.watch_link(now)
        self.privacy_tick(now)
        if self.mount is not None:
            self.mount.reforward(now)
        self.falls_between_frames(now)
        if self.bus.event_subscriber_appeared(now):
            self.outbox.subscriber_appeared(now)
        self.outbox.tick(now, self.bus.event_subscribed)
        self.history.tick(now)
        self.absence_notices()
        if self.subreaper and now >= self._next_reap:
            self._next_reap = now + 1.0
            orphans.reap_adopted(self.outbox.hooks.pids())
        storage = self.storage()
        self.rt.row.set("unstored", storage["unstored_events"])
        self.rt.row.set("storage_fault", 0.0 if storage["state"] == "ok" else 1.0)

    def privacy_tick(self, now: float) -> None:
        """The pause for privacy's schedule (its end, the order to the capture stage) and what its start and end
        change here: no pose in the state replies while paused; a fresh fall detector (the camera's learned
        geometry kept) and a fresh frame clock when watching resumes; the supervisor told (its status and
        systemd's STATUS= line)."""
        self.privacy.tick(now)
        pause = self.privacy.pause
        if pause != self._told_pause:       # a pause began, ended, or was made longer or shorter
            self._told_pause = pause
            self._report()
        paused = pause is not None
        if paused == self._was_paused:
            return
        self._was_paused = paused
        if paused:
            self.bus.latest.set_pose(None)
        else:
            self.falls.start_afresh()
            self._frame_at, self._frame_t = now, None

    def _ask_pause(self, request) -> dict:
        """A query on privacy/pause (a Zenoh thread): the keeper's answer; a pause clears the state's pose at once."""
        message = self.privacy.ask(request)
        if message["paused"]:
            self.bus.latest.set_pose(None)
        return message

    def _open_fall(self) -> str | None:
        """The id of the newest fall event that is open (its last message is not ``recovered``) and has a message
        nobody acknowledged (a Zenoh thread: the journal is thread-safe); None when there is none."""
        journal = self.outbox.journal
        for event_id in reversed(list(dict.fromkeys(e.id for e in journal.unacknowledged()))):
            stored = journal.get(event_id)
            if stored and stored[-1].event.state != "recovered":
                return event_id
        return None

    def _report(self) -> None:
        """Tell the supervisor the pause for privacy, the robot id conflict and the presence together (its report
        mailbox keeps only the latest message, so none may replace another)."""
        self.rt.report(robot_id_conflict=self._conflict_state, privacy=self.privacy.status(),
                       presence=self.presence())

    def falls_between_frames(self, now: float) -> None:
        """The alarms due without a frame: a restored fall's when due; and when no frame has been handled for
        ``tick_after_s``, the detectors' timers run on to the capture clock's now (the monotonic clock, or for an
        unpaced replay, whose capture clock runs ahead of it, the last frame's capture time plus the time since).
        A frame that comes later, with an older capture time, raises nothing twice (FallDetector.tick)."""
        quiet = now - self._frame_at
        frameless = quiet >= self.tick_after_s and not self.paused        # paused for privacy: nothing to time
        events = self.restored.due(now, self.falls, quiet if frameless else None)
        if frameless:
            t = now if self._frame_t is None else max(now, self._frame_t + quiet)
            ticked = self.falls.tick(t, quiet)
            self.restored.observe(ticked)
            events += ticked
        for event in events:
            self.outbox.post(stamp_event(event))

    def storage(self) -> dict:
        """The state directory as the status shows it: ``ok``, or ``degraded`` with the reason and the fix."""
        journal = self.outbox.journal
        unstored = journal.pending_in_memory
        history = self.history.store
        problems = [p for p in (journal.last_error, getattr(history, "last_error", "")) if p]
        out = {"state": "degraded" if problems or unstored else "ok", "unstored_events": unstored,
               "fallback": str(journal.fallback_path) if journal.fallback_path else None}
        if out["state"] != "ok":
            out["reason"] = "; ".join(problems) or f"{unstored} fall-event messages wait to be written"
            out["fix"] = ("free disk space or make pipeline.state_dir writable; meanwhile fall events are kept "
                          "in memory and in the fallback file, republished until acknowledged")
            if journal.fallback_error:
                out["fallback_error"] = journal.fallback_error
            if getattr(history, "dropped", 0):
                out["history_rows_dropped"] = history.dropped
        return out

    def publish_status(self, status: dict) -> None:
        """The supervisor's status plus the ``zenoh`` and ``events`` parts."""
        status = dict(status)
        status["zenoh"] = self.bus.status()
        self.report_conflict(status["zenoh"].get("robot_id_conflict"))
        status["events"] = self.outbox.status()
        status["events"]["acks"]["rejected"] = self.bus.acks_rejected
        status["falls"] = self.falls.status()
        if self.mount is not None and "geometry" in status["falls"]:
            geometry = status["falls"]["geometry"]
            geometry["robot_mount"] = {**geometry.get("robot_mount", {}), **self.mount.status()}
        if self.restored.open:
            status["falls"]["restored_open"] = self.restored.status()
        status["storage"] = self.storage()
        self.privacy_status(status)
        if self.ros2 is not None:
            status["ros2"] = self.ros2.status()
        now = clock.now()
        self.watching(status, now)
        watch = self.watch.state()          # absent while starting: no judgement yet (WatchLoss.state)
        if watch is not None:
            status["watch"] = watch
        status["presence"] = self.presence()
        self.bus.put_status(status_message(status, self.rt.config.robot_id, now))

    def privacy_status(self, status: dict) -> None:
        """The status's ``privacy`` (the keeper's, now) and, while paused, ``state: paused`` and no ``blind``
        (the supervisor says so too once the capture stage has closed the camera: this covers the moment
        between)."""
        status["privacy"] = self.privacy.status()
        if self.privacy.paused and status.get("state") in (*WATCHING_STATES, "paused"):
            status["state"] = "paused"
            status["blind"] = None
        elif not self.privacy.paused and status.get("state") == "paused":
            status["state"] = "running"         # resumed a moment ago; the supervisor follows

    def report_conflict(self, conflict: dict | None) -> None:
        """Another daemon with our robot id (``zenoh.robot_id_conflict``), or its end, told to the supervisor when
        it changes: systemd's STATUS= line says it (daemon.supervisor.status_text)."""
        others = list(conflict["other_daemons"]) if conflict else None
        if others != self._conflict_said:
            self._conflict_said = others
            self._conflict_state = conflict
            self._report()

    def watching(self, status: dict, now: float) -> None:
        """Whether posed watches, judged on each status once (:class:`WatchLoss`: the status's ``watch``, its
        times on the status's own clock); not watching for ``hooks.watch_lost_after_s``, or watching again after
        that: logged and handed to ``hooks.on_watch_lost`` (:mod:`daemon.outbox.watch_hooks`)."""
        notice = self.watch.update(status, now, clock.wall_from_monotonic(now))
        if notice is None:
            return
        fields = notice.to_json()
        said = dict(reason=fields["reason"], not_watching_s=fields["not_watching_s"],
                    hooks=len(self.rt.config.hooks.on_watch_lost))
        if notice.watching:
            self.rt.log.info("watch_back", **said)
        else:
            self.rt.log.error("watch_lost", **said, note="no fall can be alarmed while posed does not watch")
        if self.watch_hooks is not None:
            self.watch_hooks.submit(notice)

    def presence(self) -> dict | None:
        """The status's ``presence`` (:meth:`PresenceWatch.state`); None without the history or with
        ``falls.absence_enabled`` false."""
        watch = self.history.presence
        return None if watch is None else watch.state()

    def absence_notices(self) -> None:
        """The person not seen for longer than usual, or seen again after that (:class:`PresenceWatch`, fed by the
        history recorder): logged and handed to ``hooks.on_absent``; the supervisor told while it lasts (its
        STATUS= line says it, daemon.supervisor.status_text), again each minute as it grows."""
        for notice in self.history.notices():
            self._said_absence(notice)
        watch = self.history.presence
        told = None
        if watch is not None and watch.absent_since is not None:       # per frame: no status object built
            told = (watch.absent_since, int(watch.absent_s // 60))
        if told != self._told_presence:
            self._told_presence = told
            self._report()

    def _said_absence(self, notice: AbsenceNotice) -> None:
        fields = notice.to_json()
        said = dict(last_seen=clock.iso(notice.last_seen_unix) if notice.last_seen_unix is not None else None,
                    absent_s=fields["absent_s"], usual_s=fields["usual_s"],
                    notice_after_s=fields["notice_after_s"], hooks=len(self.rt.config.hooks.on_absent))
        if notice.absent:
            self.rt.log.error("person_absent", **said, days=notice.days,
                              note="the person has not been seen for longer than on any of the last days at this "
                                   "time of day: they may have fallen out of view")
        else:
            self.rt.log.info("person_back", **said)
        if self.absent_hooks is not None:
            self.absent_hooks.submit(notice)

    def close(self) -> None:
        """Close everything but the session (the ``with`` around the stage closes it)."""
        self.bus.forget()
        self.outbox.close(hook_timeout_s=0.5)     # then TERM, KILL: within pipeline.shutdown_timeout_s
        if self.watch_hooks is not None:
            self.watch_hooks.close(timeout=0.5)
        if self.absent_hooks is not None:
            self.absent_hooks.close(timeout=0.5)
        self.rt.row.set("unstored", self.outbox.journal.pending_in_memory)   # the supervisor says it at stop
        if self.subreaper:                          # what the hooks left behind (setsid, env -i): adopted here
            left = [p for p in orphans.descendants(os.getpid()) if not _is_resource_tracker(p)]
            if left:
                self.rt.log.warning("hook_children_ended", pids=left[:20], count=len(left),
                                    note="processes the hooks left running (setsid) ended with the publisher")
                orphans.end(left)
        self.history.close()
        self.privacy.close()                       # a running pause stays in privacy.json for the next start
        self.falls.close()                         # keep the geometry learned from people

    def _send_event(self, obj: dict) -> bool:
        """Publish one fall-event message (and to ROS 2 when enabled); False when there is no session."""
        out = event_message(obj)
        sent = self.bus.put_event(out)
        if sent and self.ros2 is not None:
            self.ros2.publish_event(out)
        return sent

    # Zenoh threads
    def _stored_events(self, since: float | None, until: float | None, limit: int, event_id: str | None = None):
        return self.outbox.journal.query(since, until, limit, event_id=event_id)

    def _acknowledge(self, event_id: str, state: str | None, by: str | None) -> None:
        self.outbox.acknowledge(event_id, state, by)


def _pause_log(cfg, log):
    """The history file's record of the pauses (``PauseLog``, table ``paused``), or None without a history
    (``falls.history_enabled`` false) or when it cannot be opened (said once; the pauses work without it)."""
    if not cfg.falls.history_enabled:
        return None
    try:
        from posed.daemon.history.paused import PauseLog

        return PauseLog(paths.history_path(cfg.pipeline), log)
    except Exception as exc:
        log.error("pause_log_unavailable", error=repr(exc), path=str(paths.history_path(cfg.pipeline)),
                  note="pauses for privacy work, but the daily report cannot list them")
        return None


def _presence_watch(cfg, log) -> PresenceWatch | None:
    """The person's presence (``falls.absence_enabled``), learned from the history file: None without one
    (``falls.history_enabled`` false)."""
    if not (cfg.falls.history_enabled and cfg.falls.absence_enabled):
        return None
    from posed.daemon.timeparse import local_zone

    return PresenceWatch(paths.history_path(cfg.pipeline), cfg.robot_id, cfg.falls, log, tz=local_zone())


def _is_resource_tracker(pid: int) -> bool:
    try:
        return b"resource_tracker" in Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False


def run(rt: StageRuntime) -> None:
    with contextlib.ExitStack() as stack:
        with rt.step():
            stage = PublisherStage(rt, stack)
        stack.callback(stage.close)
        inbox = rt.input
        stage.try_open(clock.now())
        rt.ready()
        while True:
            rt.beat()
            rt.check_stop()
            now = clock.now()
            stage.try_open(now)
            stage.periodic(now)
            msg = inbox.wait(0.05)
            if msg is None:
                continue
            with rt.step():
                t_in = clock.now()
                stage.handle(msg)
                t_out = clock.now()
            rt.done(t_out - t_in, origin(msg), t_out)
