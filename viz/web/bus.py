"""The hub's link to a robot: the Zenoh client (``client.PosedClient``) subscribed to its pose, status,
events and liveliness; acknowledgements and the event history go through the same client (the ack is the
put on ``posed/ROBOT/events/ack`` that every receiver uses). The one module that touches Zenoh here."""

from __future__ import annotations

from posed.viz.web.hub import Hub, caveats_of

HISTORY_SINCE = "7d"
HISTORY_LIMIT = 200
ACK_CONFIRM_S = 5.0


class RobotLink:
    """Feeds ``hub`` from ``robot`` over ``client`` (a ``client.PosedClient``; the caller owns it)."""

    def __init__(self, client, hub: Hub, robot: str) -> None:
        self.client, self.hub, self.robot = client, hub, robot
        client.on_pose(robot, hub.on_pose)
        client.on_status(robot, hub.on_status)
        client.on_event(robot, hub.on_event)
        client.on_alive(lambda a: hub.on_alive(a.alive), robot=robot)

    def ack(self, event_id: str, by: str | None = None) -> bool:
        """Acknowledge every message of the event so far, as ``by`` (the name the page's user gave; "posed
        web" when none); True once the robot's journal shows it."""
        ok = self.client.ack(self.robot, event_id, by=by or "posed web", confirm_s=ACK_CONFIRM_S)
        self.hub.on_acked(event_id, ok)
        return ok

    def history(self) -> list[dict]:
        """The robot's stored event messages of the last week, oldest first, as JSON objects."""
        out = []
        for e in self.client.history(self.robot, since=HISTORY_SINCE, limit=HISTORY_LIMIT):
            ev = e.event
            out.append({"id": ev.id, "state": ev.state, "wall_time": ev.wall_time, "confidence": ev.confidence,
                        "published_at": e.published_at, "acked_at": e.acked_at, "acked_by": e.acked_by,
                        **caveats_of(ev.extra)})
        return out
