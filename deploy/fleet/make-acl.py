#!/usr/bin/env python3
"""make-acl.py: a secured fleet's access control with one certificate per robot (stdlib only).

    python3 deploy/fleet/make-acl.py OUT --robot kitchen --robot bedroom \\
        [--receiver caregiver-app --receiver posed-admin] [--watchers any | --watcher family-tablet ...]

writes, from the shipped templates deploy/fleet/router-tls.json5 and deploy/zenoh/posed-daemon.json5:

* OUT/router-tls.json5: the router's config, in which robot X's certificate (CN posed-daemon.X, made by
  ``make-certs.sh DIR --robot X``) may publish, reply, declare its queryables and acknowledgement subscription and
  show liveliness tokens only under posed/X/**, and receives only posed/X's acknowledgements. The receivers are
  those given (default: the template's); the watchers are any other certificate of the CA (``--watchers any``,
  as shipped) or only the CNs given with ``--watcher``.
* OUT/ROBOT/posed-daemon.json5 for each robot: the template whose subject "daemons" admits posed-daemon.ROBOT, so
  that two daemons given that robot id (on one machine, or through the router) still find each other.

Everything else (the receivers' acknowledgements, history and privacy pause, the camera mount, the daemon's subject
"router", the paths /etc/posed/tls/...) is the templates' own: ``--shared`` writes the shipped single-certificate
setup (CN posed-daemon for every robot) and reproduces the templates. Output is JSON (valid JSON5) after a comment
line. deploy/fleet/README.md, "One certificate per robot", is the step by step.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

DEPLOY = Path(__file__).resolve().parents[1]
ROUTER_TEMPLATE = DEPLOY / "fleet" / "router-tls.json5"
DAEMON_TEMPLATE = DEPLOY / "zenoh" / "posed-daemon.json5"
ROBOT_ID = re.compile(r"[A-Za-z0-9_\-]+")      # posed's robot_id (daemon/config/schema.py)
MAX_ROBOT_ID = 64 - len("posed-daemon.")       # a certificate's CN holds at most 64 characters
SHARED_CN = "posed-daemon"
ANY_ROBOT = "posed/*/"                         # how the templates' daemon rules name "any robot's keys"


class Problem(Exception):
    """What is wrong with the input, and the fix."""


def robot_cn(robot: str) -> str:
    """The common name of ``robot``'s own certificate (make-certs.sh DIR --robot ROBOT)."""
    return f"{SHARED_CN}.{robot}"


def check_robot_id(robot: str) -> str:
    if not ROBOT_ID.fullmatch(robot):
        raise Problem(f"--robot {robot!r} is not a valid robot id: posed's robot_id is letters, digits, '_' and '-' "
                      f"only (config.yaml robot_id, pattern [A-Za-z0-9_-]+); give that robot's robot_id")
    if len(robot) > MAX_ROBOT_ID:
        raise Problem(f"--robot {robot!r} is too long for a certificate: at most {MAX_ROBOT_ID} characters "
                      f"(CN posed-daemon.ROBOT holds at most 64)")
    return robot


_JSON5 = re.compile(r'(?P<string>"(?:[^"\\\n]|\\.)*")|(?P<comment>//[^\n]*|/\*.*?\*/)'
                    r'|(?P<key>[A-Za-z_][A-Za-z0-9_]*)(?=\s*:)'
                    r'|(?P<comma>,)(?=(?:\s|//[^\n]*|/\*.*?\*/)*[}\]])|(?P<other>[^"/,A-Za-z_]+|.)', re.S)


def read_json5(path: Path):
    """The subset of JSON5 the shipped templates are written in: comments, unquoted keys, trailing commas,
    double-quoted strings."""
    parts = []
    for m in _JSON5.finditer(path.read_text()):
        if m.lastgroup in ("comment", "comma"):
            continue
        parts.append(json.dumps(m.group()) if m.lastgroup == "key" else m.group())
    try:
        return json.loads("".join(parts))
    except ValueError as e:
        raise Problem(f"{path}: not the JSON5 subset make-acl.py reads ({e}); restore it from the checkout") from e


def _by_id(items: list[dict], what: str, ident: str) -> dict:
    for item in items:
        if item.get("id") == ident:
            return item
    raise Problem(f"the template has no {what} {ident!r}; restore it from the checkout")


def router_config(template: dict, robots: list[str] | None, receivers: list[str] | None,
                  watchers: list[str] | None) -> dict:
    """The router's config. ``robots``: one certificate per robot (None: the shared one); ``receivers``: None keeps
    the template's; ``watchers``: None lets any certificate of the CA watch (as shipped), else only these CNs."""
    cfg = json.loads(json.dumps(template))
    acl = cfg["access_control"]
    if receivers is not None:
        _by_id(acl["subjects"], "subject", "receivers")["cert_common_names"] = list(receivers)
    daemon_subjects = ["daemons"]
    if robots is not None:
        daemon_subjects = _per_robot_daemons(acl, robots)
    if watchers is not None:
        _watchers_only(acl, watchers, daemon_subjects)
    return cfg


def _per_robot_daemons(acl: dict, robots: list[str]) -> list[str]:
    """Replace the subject "daemons" (CN posed-daemon) by one subject per robot, each allowed the daemons' rules on
    its own posed/ROBOT/ keys only (a rule on every robot's keys, posed/*/..., is narrowed; one on posed/** — the
    stations' subscriptions and queries passed to a daemon — is kept as it is)."""
    policy = next((p for p in acl["policies"] if p["subjects"] == ["daemons"]), None)
    if policy is None:
        raise Problem("the router template has no policy for the subject 'daemons'; restore it from the checkout")
    subject = _by_id(acl["subjects"], "subject", "daemons")
    if subject.get("cert_common_names") != [SHARED_CN]:
        raise Problem(f"the router template's subject 'daemons' is not CN {SHARED_CN}; restore it from the checkout")
    rules = {r: _by_id(acl["rules"], "rule", r) for r in policy["rules"]}
    narrowed = {r for r, rule in rules.items() if all(k.startswith(ANY_ROBOT) for k in rule["key_exprs"])}

    def own(rule: dict, robot: str) -> dict:
        return dict(rule, id=f"{rule['id']}_{robot}",
                    key_exprs=[f"posed/{robot}/{k[len(ANY_ROBOT):]}" for k in rule["key_exprs"]])

    acl["rules"] = [r for rule in acl["rules"]
                    for r in ([own(rule, robot) for robot in robots] if rule["id"] in narrowed else [rule])]
    new_subjects = [{"id": f"daemon_{robot}", "cert_common_names": [robot_cn(robot)]} for robot in robots]
    new_policies = [{"rules": [f"{r}_{robot}" if r in narrowed else r for r in policy["rules"]],
                     "subjects": [f"daemon_{robot}"]} for robot in robots]
    i = acl["subjects"].index(subject)
    acl["subjects"][i:i + 1] = new_subjects
    i = acl["policies"].index(policy)
    acl["policies"][i:i + 1] = new_policies
    return [s["id"] for s in new_subjects]


def _watchers_only(acl: dict, watchers: list[str], daemon_subjects: list[str]) -> None:
    """Let only ``watchers``, the receivers and the daemons watch, instead of any certificate of the CA."""
    policy = next((p for p in acl["policies"] if p["subjects"] == ["tls_peers"]), None)
    if policy is None:
        raise Problem("the router template has no policy for the subject 'tls_peers'; restore it from the checkout")
    subjects = ["receivers", *daemon_subjects]
    if watchers:
        i = acl["subjects"].index(_by_id(acl["subjects"], "subject", "receivers"))
        acl["subjects"].insert(i + 1, {"id": "watchers", "cert_common_names": list(watchers)})
        subjects.insert(0, "watchers")
    policy["subjects"] = subjects
    acl["subjects"] = [s for s in acl["subjects"] if s["id"] != "tls_peers"]


def daemon_config(template: dict, robot: str | None) -> dict:
    """A robot's posed-daemon.json5: the template with its subject "daemons" admitting that robot's certificate
    (None: the shared CN posed-daemon)."""
    cfg = json.loads(json.dumps(template))
    subject = _by_id(cfg["access_control"]["subjects"], "subject", "daemons")
    subject["cert_common_names"] = [robot_cn(robot) if robot is not None else SHARED_CN]
    return cfg


def write(path: Path, cfg: dict, what: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"// {what}: written by deploy/fleet/make-acl.py from the shipped template (deploy/fleet/README.md,"
                    f" \"One certificate per robot\"); regenerate rather than edit\n" + json.dumps(cfg, indent=2) + "\n")
    print(path)


def _cns(values: list[str] | None, option: str) -> list[str] | None:
    if values is None:
        return None
    for v in values:
        if not re.fullmatch(r"[A-Za-z0-9_.\-]{1,64}", v):
            raise Problem(f"{option} {v!r} is not a certificate common name make-certs.sh makes: letters, digits, "
                          f"'.', '_' and '-', at most 64 characters")
    return values


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="make-acl.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path, help="folder to write router-tls.json5 and ROBOT/posed-daemon.json5 into")
    ap.add_argument("--robot", action="append", metavar="ROBOT_ID", help="a robot's robot_id (repeat for each)")
    ap.add_argument("--shared", action="store_true",
                    help="the shipped setup instead: one certificate (CN posed-daemon) for every robot")
    ap.add_argument("--receiver", action="append", metavar="CN",
                    help="a CN that may acknowledge, read the history and pause through the router (repeat; "
                         "default: the template's caregiver-app, posed-admin)")
    ap.add_argument("--watchers", choices=["any"], help="any other certificate of the CA may watch (the default)")
    ap.add_argument("--watcher", action="append", metavar="CN",
                    help="only these CNs (and the receivers) may watch through the router (repeat)")
    ap.add_argument("--router-template", type=Path, default=ROUTER_TEMPLATE)
    ap.add_argument("--daemon-template", type=Path, default=DAEMON_TEMPLATE)
    args = ap.parse_args(argv)
    try:
        if args.shared == bool(args.robot):
            raise Problem("give the robots' ids (--robot kitchen --robot bedroom: one certificate per robot), or "
                          "--shared for the shipped single certificate")
        if args.watchers and args.watcher:
            raise Problem("--watchers any and --watcher CN exclude each other: any certificate may watch, or only "
                          "those listed")
        robots = [check_robot_id(r) for r in args.robot or []]
        if len(set(robots)) != len(robots):
            raise Problem(f"a robot id is given twice ({', '.join(sorted({r for r in robots if robots.count(r) > 1}))}"
                          f"): give each robot once")
        receivers = _cns(args.receiver, "--receiver")
        watchers = _cns(args.watcher, "--watcher")
        router = router_config(read_json5(args.router_template), robots or None, receivers, watchers)
        daemon = read_json5(args.daemon_template)
        write(args.out / "router-tls.json5", router, "the fleet's router")
        if args.shared:
            write(args.out / "posed-daemon.json5", daemon_config(daemon, None), "every robot's daemon")
        for robot in robots:
            write(args.out / robot / "posed-daemon.json5", daemon_config(daemon, robot), f"robot {robot}'s daemon")
    except Problem as e:
        print(f"make-acl.py: {e}", file=sys.stderr)
        return 64
    return 0


if __name__ == "__main__":
    sys.exit(main())
