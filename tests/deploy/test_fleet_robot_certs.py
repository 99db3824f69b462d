"""One certificate per robot on a secured fleet (deploy/fleet/README.md, "One certificate per robot"):
deploy/zenoh/make-certs.sh ``--robot``, deploy/fleet/make-acl.py, and what the router then lets a robot's
certificate say. The router is a zenoh-python session in router mode (the stand-in for zenohd) opened from the
generated or the shipped router-tls.json5, on 127.0.0.1 over TLS; each party a client with its own certificate
from the shipped receiver.json5.

The gap closed: with the shipped single certificate (CN posed-daemon on every robot) a robot's certificate can put
a fall on another robot's keys, show its liveliness token and answer its queries, and a caregiver reads it as that
robot's; with make-acl.py's config, robot A's certificate speaks for posed/A only."""

from __future__ import annotations

import subprocess
import threading
import time
from pathlib import Path

import pytest
import zenoh

from tests.daemon.zenoh_util import free_port
from tests.deploy.fleet_certs import CAREGIVER, ROOT, fleet_certs, make_acl, make_certs, router, zenoh_json
from tests.interop.daemons import wait_for
from tests.interop.test_fleet_tls import _party

SHIPPED_ROUTER = ROOT / "deploy" / "fleet" / "router-tls.json5"
SHIPPED_DAEMON = ROOT / "deploy" / "zenoh" / "posed-daemon.json5"
FAKE_FALL = '{"forged": "fall"}'


def test_make_certs_makes_one_certificate_per_robot_under_the_installed_names(tmp_path):
    """Fails if a robot's certificate is not CN posed-daemon.ROBOT, signed by the CA, under the file names the
    shipped configs reference (posed-daemon.pem/.key, ca.pem), or if the shared certificate is made with it."""
    certs = tmp_path / "certs"
    r = make_certs(certs, "caregiver-app", "--robot", "kitchen", "--robot", "hall_2")
    assert r.returncode == 0, r.stderr
    assert not (certs / "posed-daemon.pem").exists(), "the shared certificate was made next to per-robot ones"
    for robot in ("kitchen", "hall_2"):
        d = certs / "robots" / robot
        assert sorted(p.name for p in d.iterdir()) == ["ca.pem", "posed-daemon.key", "posed-daemon.pem"]
        assert (d / "posed-daemon.key").stat().st_mode & 0o077 == 0
        subject = subprocess.run(["openssl", "x509", "-in", str(d / "posed-daemon.pem"), "-noout", "-subject"],
                                 capture_output=True, text=True, check=True).stdout
        assert subject.strip().replace(" ", "") == f"subject=CN=posed-daemon.{robot}", subject
        ok = subprocess.run(["openssl", "verify", "-CAfile", str(certs / "ca.pem"), str(d / "posed-daemon.pem")],
                            capture_output=True, text=True)
        assert ok.returncode == 0, ok.stdout + ok.stderr
    assert (certs / "caregiver-app.pem").exists()


@pytest.mark.parametrize("bad", ["two words", "kitchen/1", "a.b", "", "x" * 52])
def test_an_invalid_robot_id_is_refused_naming_the_rule(tmp_path, bad):
    """Fails if make-certs.sh or make-acl.py accept a robot id posed would refuse (or one too long for a CN),
    write anything for it, or refuse it without saying what a robot id may be."""
    r = make_certs(tmp_path / "certs", "--robot", "kitchen", "--robot", bad)
    assert r.returncode == 64, r.stdout + r.stderr
    assert f"'{bad}'" in r.stderr and ("letters, digits, '_' and '-'" in r.stderr or "at most 51" in r.stderr)
    assert not (tmp_path / "certs").exists(), "certificates were written before the robot id was checked"
    r = make_acl(tmp_path / "acl", "--robot", "kitchen", "--robot", bad)
    assert r.returncode == 64, r.stdout + r.stderr
    assert repr(bad) in r.stderr and ("letters, digits, '_' and '-'" in r.stderr or "at most 51" in r.stderr)
    assert not (tmp_path / "acl").exists()


def test_make_acl_needs_robots_or_shared(tmp_path):
    r = make_acl(tmp_path / "acl")
    assert r.returncode == 64 and "--robot" in r.stderr and "--shared" in r.stderr, r.stderr


def test_make_acl_for_the_shared_certificate_reproduces_the_shipped_files(tmp_path):
    """Fails if make-acl.py's reading or writing of the templates changes anything (compared as Zenoh reads
    them): the per-robot output below is then only its own changes."""
    r = make_acl(tmp_path, "--shared")
    assert r.returncode == 0, r.stderr
    assert zenoh_json(tmp_path / "router-tls.json5") == zenoh_json(SHIPPED_ROUTER)
    assert zenoh_json(tmp_path / "posed-daemon.json5") == zenoh_json(SHIPPED_DAEMON)


def test_per_robot_configs_change_only_the_daemons_parts(tmp_path):
    """The diff of the generated files against the shipped ones, as Zenoh reads them: in the router, the subject
    "daemons" becomes one subject per robot, and the daemons' rules on every robot's keys (posed/*/...) become one
    copy per robot on its own keys; everything else (receivers, watchers, history, pause, mount, TLS) is equal.
    In each robot's daemon config, only the subject "daemons" differs: its own CN."""
    r = make_acl(tmp_path, "--robot", "A", "--robot", "B")
    assert r.returncode == 0, r.stderr
    shipped, made = zenoh_json(SHIPPED_ROUTER), zenoh_json(tmp_path / "router-tls.json5")
    assert {k: v for k, v in made.items() if k != "access_control"} == \
        {k: v for k, v in shipped.items() if k != "access_control"}
    s_acl, m_acl = shipped["access_control"], made["access_control"]
    assert {k: v for k, v in m_acl.items() if k not in ("rules", "subjects", "policies")} == \
        {k: v for k, v in s_acl.items() if k not in ("rules", "subjects", "policies")}
    s_rules = {r["id"]: r for r in s_acl["rules"]}
    m_rules = {r["id"]: r for r in m_acl["rules"]}
    narrowed = ["daemon_in", "daemon_declares_in", "daemon_acks_in", "acks_to_daemon"]
    assert set(m_rules) == (set(s_rules) - set(narrowed)) | {f"{n}_{x}" for n in narrowed for x in "AB"}
    for rid in set(s_rules) - set(narrowed):
        assert m_rules[rid] == s_rules[rid], rid
    for n in narrowed:
        for x in "AB":
            want = dict(s_rules[n], id=f"{n}_{x}",
                        key_exprs=[k.replace("posed/*/", f"posed/{x}/") for k in s_rules[n]["key_exprs"]])
            assert m_rules[f"{n}_{x}"] == want
    s_subjects = {s["id"]: s for s in s_acl["subjects"]}
    m_subjects = {s["id"]: s for s in m_acl["subjects"]}
    assert set(m_subjects) == set(s_subjects) - {"daemons"} | {"daemon_A", "daemon_B"}
    for sid in set(s_subjects) - {"daemons"}:
        assert m_subjects[sid] == s_subjects[sid], sid
    for x in "AB":
        assert m_subjects[f"daemon_{x}"] == dict(s_subjects["daemons"], id=f"daemon_{x}",
                                                 cert_common_names=[f"posed-daemon.{x}"])
    s_pol = [p for p in s_acl["policies"] if p["subjects"] != ["daemons"]]
    m_pol = [p for p in m_acl["policies"] if not p["subjects"][0].startswith("daemon_")]
    assert m_pol == s_pol
    (daemons,) = [p for p in s_acl["policies"] if p["subjects"] == ["daemons"]]
    for x in "AB":
        assert [p["rules"] for p in m_acl["policies"] if p["subjects"] == [f"daemon_{x}"]] == \
            [[rid if rid not in narrowed else f"{rid}_{x}" for rid in daemons["rules"]]]
    for x in "AB":
        shipped_d, made_d = zenoh_json(SHIPPED_DAEMON), zenoh_json(tmp_path / x / "posed-daemon.json5")
        for subject in shipped_d["access_control"]["subjects"]:
            if subject["id"] == "daemons":
                subject["cert_common_names"] = [f"posed-daemon.{x}"]
        assert made_d == shipped_d


def test_receivers_and_watchers_are_given(tmp_path):
    """Fails if --receiver does not replace the router's receivers, or if --watcher does not limit who may watch
    through the router to the listed watchers, the receivers and the robots."""
    r = make_acl(tmp_path, "--robot", "A", "--receiver", "nurse", "--watcher", "family-tablet")
    assert r.returncode == 0, r.stderr
    acl = zenoh_json(tmp_path / "router-tls.json5")["access_control"]
    subjects = {s["id"]: s["cert_common_names"] for s in acl["subjects"]}
    assert subjects == {"receivers": ["nurse"], "watchers": ["family-tablet"], "daemon_A": ["posed-daemon.A"]}
    (watch,) = [p for p in acl["policies"] if "watch_in" in p["rules"]]
    assert watch["subjects"] == ["watchers", "receivers", "daemon_A"]
    r = make_acl(tmp_path / "bad", "--robot", "A", "--watcher", "no spaces")
    assert r.returncode == 64 and "'no spaces'" in r.stderr, r.stderr


class _Caregiver:
    """What a caregiver's station receives of robot B: its samples and the liveliness tokens it sees."""

    def __init__(self, session: zenoh.Session, robot: str) -> None:
        self.lock = threading.Lock()
        self.samples: list[tuple[str, str]] = []
        self.tokens: list[str] = []
        self._subs = [session.declare_subscriber(f"posed/{robot}/**", self._sample),
                      session.liveliness().declare_subscriber(f"posed/{robot}/alive/**", self._token, history=True)]

    def _sample(self, s) -> None:
        with self.lock:
            self.samples.append((str(s.key_expr), s.payload.to_string()))

    def _token(self, s) -> None:
        with self.lock:
            self.tokens.append(str(s.key_expr))

    def seen(self) -> tuple[list, list]:
        with self.lock:
            return list(self.samples), list(self.tokens)


def forge(tmp_path: Path, certs: Path, router_cfg: Path, impostor: Path) -> dict:
    """A session holding the certificate in ``impostor`` (a folder with ca.pem, posed-daemon.pem/.key) puts a
    fall and a pose on robot B's keys, shows a token posed/B/alive/..., answers B's state and history queries;
    the same on robot A's keys is the control (it must reach the caregiver, so that nothing seen of B means
    dropped, not yet delivered). What the caregiver saw of B: samples, tokens, replies."""
    tmp_path.mkdir()
    rep = f"tls/127.0.0.1:{free_port()}"
    rt = router(tmp_path, router_cfg, certs, rep)
    parties = []
    try:
        parties.append(_party(tmp_path, certs, CAREGIVER, rep))
        caregiver = parties[-1].session
        of_b, of_a = _Caregiver(caregiver, "B"), _Caregiver(caregiver, "A")
        parties.append(_party(tmp_path, impostor, "posed-daemon", rep, name="impostor"))
        bad = parties[-1].session
        held = [bad.liveliness().declare_token(f"posed/{x}/alive/impostor.1.host") for x in "BA"]
        held += [bad.declare_queryable(k, lambda q: q.reply(q.key_expr, '{"forged": "reply"}'))
                 for k in ("posed/B/state", "posed/B/events/history/**", "posed/A/state")]

        def control(n: int) -> bool:
            bad.put("posed/A/pose", f"control {n}")
            time.sleep(0.2)
            return ("posed/A/pose", f"control {n}") in of_a.seen()[0]

        wait_for(lambda: control(0), 20, "the impostor's put on its own robot's keys (the control)")
        for _ in range(5):
            bad.put("posed/B/events/fall", FAKE_FALL)
            bad.put("posed/B/pose", '{"forged": "pose"}')
            time.sleep(0.05)
        wait_for(lambda: control(1), 20, "the control after the forged puts")
        wait_for(lambda: "posed/A/alive/impostor.1.host" in of_a.seen()[1], 20, "the control token on posed/A")
        own = [r.ok.payload.to_string() for r in caregiver.get("posed/A/state", timeout=3) if r.ok is not None]
        assert own == ['{"forged": "reply"}'], f"the control query on posed/A was not answered: {own}"
        replies = [str(r.ok.key_expr) for key in ("posed/B/state", "posed/B/events/history/**")
                   for r in caregiver.get(key, timeout=3) if r.ok is not None]
        samples, tokens = of_b.seen()
        return {"samples": samples, "tokens": tokens, "replies": replies}
    finally:
        for p in parties:
            p.close()
        rt.close()


@pytest.mark.timeout(180)
def test_a_robots_certificate_cannot_speak_for_another_robot(tmp_path):
    """Robot A's own certificate, through the router configured by make-acl.py: its fall and pose on posed/B are
    dropped, its token posed/B/alive/* is not seen, its answers to B's queries never come; and the old shared
    certificate is no longer admitted to speak at all. The same test against the shipped router-tls.json5 with
    the shared certificate fails (test_the_shared_certificate_speaks_for_any_robot shows it does)."""
    certs = fleet_certs(tmp_path / "certs", ("A", "B"))
    r = make_acl(tmp_path / "acl", "--robot", "A", "--robot", "B")
    assert r.returncode == 0, r.stderr
    seen = forge(tmp_path / "own", certs, tmp_path / "acl" / "router-tls.json5", certs / "robots" / "A")
    assert seen == {"samples": [], "tokens": [], "replies": []}, f"A's certificate spoke for robot B: {seen}"


@pytest.mark.timeout(180)
def test_the_shared_certificate_speaks_for_any_robot(tmp_path):
    """The gap, on the shipped single-certificate setup (router-tls.json5, CN posed-daemon on every robot): a
    robot's certificate puts a fall on robot B's keys, shows B's liveliness token and answers B's queries, and
    the caregiver receives it all as robot B's. Fails once the shipped router binds robots to their keys."""
    certs = fleet_certs(tmp_path / "certs", ("A", "B"))
    shared = tmp_path / "shared"
    shared.mkdir()
    for name in ("ca.pem", "posed-daemon.pem", "posed-daemon.key"):
        (shared / name).write_bytes((certs / name).read_bytes())
    seen = forge(tmp_path / "shipped", certs, SHIPPED_ROUTER, shared)
    assert ("posed/B/events/fall", FAKE_FALL) in seen["samples"], seen
    assert "posed/B/alive/impostor.1.host" in seen["tokens"], seen
    assert "posed/B/state" in seen["replies"], seen


@pytest.mark.timeout(180)
def test_the_shared_certificate_is_not_a_robot_on_the_per_robot_router(tmp_path):
    """A leftover shared certificate (CN posed-daemon) on a router configured by make-acl.py speaks for no robot:
    fails if the generated router still admits the shared CN."""
    certs = fleet_certs(tmp_path / "certs", ("A", "B"))
    r = make_acl(tmp_path / "acl", "--robot", "A", "--robot", "B")
    assert r.returncode == 0, r.stderr
    shared = tmp_path / "shared"
    shared.mkdir()
    for name in ("ca.pem", "posed-daemon.pem", "posed-daemon.key"):
        (shared / name).write_bytes((certs / name).read_bytes())
    with pytest.raises(AssertionError, match="the impostor's put on its own robot's keys"):
        forge(tmp_path / "leftover", certs, tmp_path / "acl" / "router-tls.json5", shared)



@pytest.mark.timeout(180)
def test_only_listed_watchers_watch_through_the_router(tmp_path):
    """With ``--watcher family-tablet`` the listed watcher and the caregiver (a receiver) receive robot A's poses
    through the real router, another certificate of the CA does not. Fails if --watcher leaves the shipped
    "any certificate watches" in place (the stranger receives them too), or if it shuts the listed ones out."""
    certs = fleet_certs(tmp_path / "certs", ("A",), "family-tablet", "stranger")
    r = make_acl(tmp_path / "acl", "--robot", "A", "--watcher", "family-tablet")
    assert r.returncode == 0, r.stderr
    rep = f"tls/127.0.0.1:{free_port()}"
    rt = router(tmp_path, tmp_path / "acl" / "router-tls.json5", certs, rep)
    parties = []
    try:
        got: dict[str, list] = {}
        for cn in (CAREGIVER, "family-tablet", "stranger"):
            parties.append(_party(tmp_path, certs, cn, rep))
            got[cn] = []
            parties[-1].session.declare_subscriber("posed/A/pose", lambda s, cn=cn: got[cn].append(1))
        parties.append(_party(tmp_path, certs / "robots" / "A", "posed-daemon", rep, name="robot-A"))
        robot = parties[-1].session

        def heard() -> bool:
            robot.put("posed/A/pose", "{}")
            time.sleep(0.2)
            return bool(got[CAREGIVER] and got["family-tablet"])

        wait_for(heard, 20, "robot A's pose at the caregiver and the listed watcher")
        for _ in range(5):
            robot.put("posed/A/pose", "{}")
            time.sleep(0.1)
        assert got["stranger"] == [], "an unlisted certificate watched through the router"
    finally:
        for p in parties:
            p.close()
        rt.close()
