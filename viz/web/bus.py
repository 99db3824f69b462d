"""The hub's link to a robot: the Zenoh client (``client.PosedClient``) subscribed to its pose, status,
events and liveliness; acknowledgements and the event history go through the same client (the ack is the
put on ``posed/ROBOT/events/ack`` that every receiver uses). The one module that touches Zenoh here.

``robot`` ``"*"``: every robot on the bus (a care home's station): the hub lists every robot's fall events, each
with its robot, and an acknowledgement goes to the robot the event is from — never to another."""

from __future__ import annotations

from posed.viz.web.fall_list import KEEP_S
from posed.viz.web.hub import EVERY_ROBOT, Hub, caveats_of

HISTORY_SINCE = f"{round(KEEP_S / 86400)}d"     # the page's window (fall_list.KEEP_S)
HISTORY_LIMIT = 2000            # stored messages per robot the page is sent at most (a week at ~100 falls a day)
ACK_CONFIRM_S = 5.0
CONFIRM_LIMIT = 10000           # the daemon's largest limit: a history asked between two times


class AckRefused(ValueError):
    """An acknowledgement this page cannot send: the event is not known here, or is another robot's."""


class RobotLink:
    """Feeds ``hub`` from ``robot`` over ``client`` (a ``client.PosedClient``; the caller owns it)."""

    history_limit = HISTORY_LIMIT

    def __init__(self, client, hub: Hub, robot: str) -> None:
        self.client, self.hub, self.robot = client, hub, robot
        client.on_pose(robot, hub.on_pose)
        client.on_status(robot, hub.on_status)
        client.on_event(robot, hub.on_event)
        client.on_alive(lambda a: hub.on_alive(a.alive, a.robot), robot=robot)

    def robot_for(self, event_id: str) -> str:
        """The robot an acknowledgement of ``event_id`` goes to: this link's robot; with every robot, the one
        the event came from (refused when the event is not known here)."""
        known = self.hub.robot_of(event_id)
        if self.robot != EVERY_ROBOT:
            if known is not None and known != self.robot:
                raise AckRefused(f"event {event_id} is robot {known}'s, not {self.robot}'s")
            return self.robot
        if known is None:
            raise AckRefused(f"event {event_id} is not among the events this page lists: reload the page")
        return known

    def ack(self, event_id: str, by: str | None = None) -> bool:
        """Acknowledge every message of the event so far, as ``by`` (the name the page's user gave; "posed
        web" when none), on the robot it is from; True once the robot's journal shows it. The journal is asked
        for this event's messages by its id (``PosedClient.ack``'s confirmation: however old the event, not
        the whole history)."""
        robot = self.robot_for(event_id)
        ok = self.client.ack(robot, event_id, by=by or "posed web", confirm_s=ACK_CONFIRM_S)
        self.hub.on_acked(event_id, ok)
        return ok

    def history(self, since: float | None = None, until: float | None = None) -> list[dict]:
        """The robot's stored event messages of the page's window, oldest first, as JSON objects (at most
        ``HISTORY_LIMIT`` per robot, the newest); or those between ``since`` and ``until`` (unix s; at most
        ``CONFIRM_LIMIT``)."""
        out = []
        window = (HISTORY_SINCE, HISTORY_LIMIT) if since is None else (since, CONFIRM_LIMIT)
        for e in self.client.history(self.robot, since=window[0], until=until, limit=window[1]):
            ev = e.event
            out.append({"id": ev.id, "state": ev.state, "robot": e.robot, "wall_time": ev.wall_time,
                        "confidence": ev.confidence, "published_at": e.published_at, "acked_at": e.acked_at,
                        "acked_by": e.acked_by, **caveats_of(ev.extra)})
        return out
