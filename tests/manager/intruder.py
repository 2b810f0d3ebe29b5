"""A Zenoh peer that tries to find, read and disturb a zencosim run (tests/manager/test_secure_run.py).

``python intruder.py JSON`` with ``{"endpoint": ..., "run_id": ..., "config": {...}, "publish": bool}``
opens a peer session to ``endpoint`` with the run's transport settings and the credentials given in
``config`` (Zenoh configuration keys and values, e.g. ``transport/link/tls/root_ca_certificate``),
tries every way to learn about the run (queries, liveliness, a subscription to ``zencosim/**``) and,
with ``publish``, sends a STOP and garbage on the run's keys. It prints what it got as JSON. Apart from its endpoint and credentials it is not zencosim's own code: an intruder owes it nothing.
"""
from __future__ import annotations

import json
import ssl
import sys
import time

import zenoh

LISTEN_S = 2.0  # how long the subscription listens for the run's traffic (after the queries)
QUERY_S = 3.0  # how long a query waits for answers


def session_config(endpoint: str, credentials: dict) -> zenoh.Config:
    config = zenoh.Config()
    for key, value in {"mode": "peer", "scouting/multicast/enabled": False, "scouting/gossip/enabled": False,
                       "connect/endpoints": [endpoint], "transport/unicast/lowlatency": True,
                       "transport/unicast/qos/enabled": False}.items():
        config.insert_json5(key, json.dumps(value))
    for key, value in credentials.items():
        config.insert_json5(key, json.dumps(value))
    return config


def server_certificate(endpoint: str) -> str | None:
    """The subject of the certificate a TLS endpoint shows to anyone who connects (no client certificate)."""
    host, _, port = endpoint.split("/", 1)[1].rpartition(":")
    try:
        pem = ssl.get_server_certificate((host, int(port)), timeout=5)
    except (OSError, ssl.SSLError) as error:
        return f"refused: {error}"
    return pem.splitlines()[0] if pem else None


def intrude(endpoint: str, run_id: str, config: dict, publish: bool) -> dict:
    found: dict = {"endpoint": endpoint}
    if endpoint.startswith("tls/"):
        found["certificate"] = server_certificate(endpoint)
    try:
        session = zenoh.open(session_config(endpoint, config))
    except zenoh.ZError as error:
        found["session"] = f"refused: {error}"
        return found
    with session:
        deadline = time.monotonic() + 5.0
        while not list(session.info.peers_zid()) and time.monotonic() < deadline:
            time.sleep(0.1)
        found["peers"] = len(list(session.info.peers_zid()))
        heard: list[str] = []
        subscriber = session.declare_subscriber("zencosim/**", lambda sample: heard.append(str(sample.key_expr)))
        # the three queries at once: each waits for its timeout when nobody answers
        runs = session.get("zencosim/*/manager/run", timeout=QUERY_S)
        queryables = session.get("zencosim/**", timeout=QUERY_S)
        tokens = session.liveliness().get("zencosim/**", timeout=QUERY_S)
        found["runs"] = [reply.ok.payload.to_string() for reply in runs if reply.ok is not None]
        found["queryables"] = [str(reply.ok.key_expr) for reply in queryables if reply.ok is not None]
        found["tokens"] = [str(reply.ok.key_expr) for reply in tokens if reply.ok is not None]
        time.sleep(LISTEN_S)
        subscriber.undeclare()  # before it publishes: a session hears its own samples
        found["heard"] = sorted(set(heard))
        if publish:
            for part in ("S1/u", "S2/u", "S1/y", "S2/y", "S1/log", "manager/go"):
                session.put(f"zencosim/{run_id}/{part}", b"\x00garbage")
            time.sleep(0.5)  # sent before the session closes
    return found


if __name__ == "__main__":
    print(json.dumps(intrude(**json.loads(sys.argv[1]))))
