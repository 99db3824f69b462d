"""A caregiver's station for a fleet: which robots are up, every robot's unacknowledged fall events (from each
robot's journal, through the router), and new events as they come. Run: python station.py tcp/ROUTER:7447; on a
secured fleet give its Zenoh config (TLS, its certificate: README.md, "A secured fleet") too:
python station.py tls/ROUTER:7447 /etc/posed/zenoh/station.json5"""

import sys
import time

from posed.client import PosedClient

with PosedClient.connect(sys.argv[1] if len(sys.argv) > 1 else "tcp/127.0.0.1:7447",
                         config_file=sys.argv[2] if len(sys.argv) > 2 else None) as posed:
    posed.on_alive(lambda a: print(f"robot {a.robot} {'up' if a.alive else 'GONE'}", flush=True))
    for entry in posed.history("*", since="7d", limit=1000):
        if entry.acked_at is None:
            print(f"open: {entry.robot} {entry.event.state} {entry.event.id} at {entry.event.wall_time}")
    posed.on_event("*", lambda robot, e: print(f"FALL {robot} {e.state} {e.id} confidence {e.confidence:.2f}",
                                               flush=True))
    while True:
        time.sleep(1)
