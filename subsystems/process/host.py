"""A subsystem process: one subsystem of a scene, in a run over Zenoh.

Started by ``zencosim run --bus zenoh`` for every subsystem, or by hand on another host with
``zencosim subsystem SCENE NAME --connect tcp/HOST:PORT``. The process runs its own replica of the
run's scheme (``manager.scheme.replica``): it executes its own commands, publishes its replies and takes the
other subsystems' replies from the network, in the Zenoh subscriber callback, so no thread hand-off
sits on the critical path. Every reply goes at once to the other subsystems (``<sub>/y``); the
manager, which only follows the run, gets them in batches (``<sub>/log``: at most ``LOG_REPLIES``
replies or ``LOG_INTERVAL_S`` old, at once after an error and at the end, and within ``SIGNAL_LOOK_S`` when the
replica waits), because on a machine with
fewer cores than processes every message a process handles costs CPU that the critical path needs.
When its replica has finished, the process reports the timing of the steps as it released them
(``<sub>/timing``). It ends on STOP, on SIGINT/SIGTERM, or when the manager disappears.
"""
from __future__ import annotations

import functools
import json
import os
import signal
import sys
import threading
import time

import numpy as np
import zenoh

from zencosim.manager.assembly import make_scheme, plan_scene, process_scope
from zencosim.manager.bus.dropped import DroppedMessages, publisher
from zencosim.manager.bus.inproc import endpoints
from zencosim.manager.bus.signals import SignalNote
from zencosim.manager.bus.timing import step_timing
from zencosim.manager.bus.zenoh_session import (
    STOP_RECEIVED,
    ZenohOptions,
    concrete_endpoint,
    coupling_publisher,
    endpoint_host,
    key,
    open_session,
    reachable,
    session_config,
    wait_for_listener,
)
from zencosim.manager.scene.load import Scene
from zencosim.manager.scheme.pacing import SPIN_SHARED_NS
from zencosim.manager.scheme.replica import Replica
from zencosim.manager.scheme.tapped import handover_size
from zencosim.manager.wire.protocol import Kind, ProtocolError, decode_header
from zencosim.manager.wire.text import printable


class HostError(RuntimeError):
    """The subsystem process could not join a run."""


def describe(scene: Scene, name: str, subsystem, listen: str | None, dropped: dict | None = None) -> bytes:
    """What the manager checks before a run (same scene, same ports), where this process listens (None:
    nowhere, a router's client), and the messages it has dropped so far (``manager.bus.dropped``)."""
    return json.dumps({
        "dropped": dropped or {},
        "subsystem": name,
        "listen": listen,
        "scene_digest": scene.digest,
        "inputs": [[p.name, p.unit] for p in subsystem.inputs],
        "outputs": [[p.name, p.unit] for p in subsystem.outputs],
        "identity": getattr(scene.subsystems[name].spec, "identity", {}),  # an FMU: its GUID and sha256
        "pid": os.getpid(),
    }).encode()


def find_run(session: zenoh.Session, scene: Scene, name: str, wait_s: float) -> dict:
    """The description of the one run that waits for subsystem ``name`` of this scene: its id and the
    endpoints of the processes already in it."""
    deadline = time.monotonic() + wait_s
    while True:
        candidates = []
        for reply in session.get("zencosim/*/manager/run", timeout=1.0):
            if reply.ok is None:
                continue
            info = json.loads(reply.ok.payload.to_bytes())
            if info.get("scene_digest") == scene.digest and name in info.get("waiting_for", []):
                candidates.append(info)
        if len(candidates) == 1:
            return candidates[0]
        if len(candidates) > 1:
            raise HostError(f"several runs wait for {name} of scene {scene.name}: "
                            f"{', '.join(c['run_id'] for c in candidates)}; choose one with --run-id")
        if time.monotonic() > deadline:
            raise HostError(f"no run of scene {scene.name} (digest {scene.digest[:12]}) waits for subsystem {name}; "
                            "is the manager started with the same scene and --set options?")
        time.sleep(0.2)


SIGNAL_LOOK_S = 0.1  # the main thread looks this often for a signal (manager.bus.signals)
EXIT_LIMIT_S = 10.0  # once stopped, the process has this long to leave the run in order


def _exit_now(name: str, reason: str) -> None:
    print(printable(f"subsystem {name}: {reason}; leaving the Zenoh session took over {EXIT_LIMIT_S:g} s, exiting now"),
          file=sys.stderr, flush=True)
    os._exit(1)


# replies per batch for the manager, at most, and how long the oldest of a batch waits at most: the manager's follower
# wakes once a batch (two_mass_damped over Zenoh, 2 cores: its CPU 12.5 µs per step with 64 replies or 10 ms, 8.7 with
# 256 or 50 ms, 8.4 with 1,024 or 0.1 s, the processes' no lower)
LOG_REPLIES = 256
LOG_INTERVAL_S = 0.05
# and a batch goes once it holds handover_size(replies sent) and the last is this old [s]: a model that ends its
# process takes with it only the replies of its last batch, a small part of those it computed
LOG_SOONEST_S = 0.01


class _Host:
    """The state of one subsystem process during a run (all callbacks take ``lock``)."""

    def __init__(self, scene: Scene, name: str, run_id: str, session: zenoh.Session) -> None:
        self.scene, self.name, self.run_id, self.session = scene, name, run_id, session
        self.plan, subsystems = plan_scene(scene)
        self.subsystem = subsystems[name]
        self.local = endpoints(self.plan, subsystems, [name])
        self.scope, self.partners = process_scope(scene, self.plan, name)
        tracked = self.plan.tracked(self.scope) if self.scope is not None else range(len(self.plan.subsystems))
        self.names = [self.plan.subsystems[i].name for i in sorted(tracked)]  # whose replies its replica takes
        self.lock = threading.Lock()
        self.finished = threading.Event()
        self.reasons: list[str] = []
        self.early: list[tuple[str, bytes]] = []  # replies that arrive before the start signal
        self.replica: Replica | None = None
        self.seen: set[str] = set()
        self.replies = coupling_publisher(session, key(run_id, name, "y"))
        self.log = coupling_publisher(session, key(run_id, name, "log"))
        self.unsent: list[bytes] = []  # replies not yet sent to the manager
        self.sent = 0  # replies sent to the manager
        self.log_due = handover_size(0, LOG_REPLIES)  # replies that make a batch once LOG_SOONEST_S has passed
        self.received = 0  # replies taken from the network (its sources')
        self.cpu_s = [0.0, 0.0]  # this process's CPU time when the run started and when its replica finished
        self.last_sent = time.monotonic()
        self.dropped = DroppedMessages()  # messages taken off the network and dropped (manager.bus.dropped)
        self.quiet = threading.local()  # the threads whose numpy overflow and invalid warnings _guarded turned off

    def stop(self, why: str) -> None:
        self.reasons.append(why)
        self.finished.set()

    def ended(self, signals: SignalNote) -> bool:
        """Whether the run has ended for this process; a signal noted since its last look ends it now."""
        if signals.received is not None and not self.finished.is_set():
            self.stop(signals.received)
        return self.finished.is_set()

    def publish(self, _name: str, reply: bytes) -> None:
        """A reply of this subsystem: to the other subsystems now, to the manager in the next batch."""
        self.replies.put(reply)
        self.unsent.append(reply)
        waited = time.monotonic() - self.last_sent
        if (len(self.unsent) >= self.log_due and waited >= LOG_SOONEST_S) or waited >= LOG_INTERVAL_S \
                or len(self.unsent) >= LOG_REPLIES or reply[1] == Kind.ERROR:
            self.send_log()

    def send_idle_log(self) -> None:
        """Send the replies the manager has not had when none has been published for ``LOG_INTERVAL_S`` (from the
        main thread, between its looks for a signal; skipped while a callback holds the lock). A replica that waits
        for a peer's reply publishes nothing new: without this, its last replies waited with it, and the manager,
        which takes every reply in order, named it as the subsystem that did not answer instead of the peer."""
        if self.unsent and time.monotonic() - self.last_sent >= LOG_INTERVAL_S and self.lock.acquire(blocking=False):
            try:
                if self.unsent and not self.finished.is_set():
                    self.send_log()
            finally:
                self.lock.release()

    def send_log(self) -> None:
        if self.unsent:
            self.log.put(b"".join(self.unsent))
            self.sent += len(self.unsent)
            self.log_due = handover_size(self.sent, LOG_REPLIES)
            self.unsent.clear()
        self.last_sent = time.monotonic()

    def on_reply(self, sender: str, sample: zenoh.Sample) -> None:
        data = sample.payload.to_bytes()
        with self.lock:
            self.received += 1
            if self.finished.is_set():  # stopping: the peers' replies no longer advance the run
                return
            if self.replica is None:
                self.early.append((sender, data))
            else:
                self._guarded(self.replica.deliver, sender, data)

    def on_go(self, sample: zenoh.Sample) -> None:
        """The start signal; anything else on ``manager/go``, or a second one, is dropped and counted."""
        try:
            go = json.loads(sample.payload.to_bytes())
            start_unix_ns, realtime = int(go["start_unix_ns"]), bool(go["realtime"])
        except (ValueError, KeyError, TypeError) as error:
            self.dropped.add(str(sample.key_expr), f"not a start signal ({type(error).__name__}: {error})",
                             publisher(sample))
            return
        # the start on this process's monotonic clock (which paces; the wall clock may be stepped)
        start_ns = time.perf_counter_ns() + (start_unix_ns - time.time_ns())
        with self.lock:
            if self.replica is not None:
                self.dropped.add(str(sample.key_expr), "a second start signal", publisher(sample))
                return
            self.cpu_s[0] = time.process_time()
            scheme = make_scheme(self.scene, self.plan, realtime, start_ns, spin_ns=SPIN_SHARED_NS, local=self.scope,
                                 cpu=self.plan.by_name(self.name).index % (os.cpu_count() or 1),
                                 who=f"subsystem {self.name}")
            self.replica = Replica(scheme, self.names, self.local, self.publish, on_drop=self.drop_reply)
            self._guarded(self.replica.start)
            for sender, data in self.early:
                self._guarded(self.replica.deliver, sender, data)
            self.early.clear()

    def on_timing(self, query: zenoh.Query) -> None:
        """The timing of the steps as this process released them, once its replica has finished."""
        with self.lock:
            finished = self.replica is not None and self.replica.finished
            report = step_timing(self.replica.result) if finished else None
            if report is not None:
                report["replies_received"] = self.received
                report["dropped"] = self.dropped.report()
                report["cpu_s"] = self.cpu_s[1] - self.cpu_s[0]  # every thread of the process, while it stepped
        if report is None:
            query.reply_err(b"the run has not finished here")
        else:
            query.reply(key(self.run_id, self.name, "timing"), json.dumps(report).encode())

    def _guarded(self, action, *args) -> None:
        """Run a replica action; an error here (a failed run) ends this process. A diverging run overflows: its
        values become infinite or NaN without a warning, and the manager's summary reports it (numpy's handling of
        both set once in each thread that runs an action — Zenoh's callback thread: its context keeps it — not
        entered and left around every reply)."""
        if not hasattr(self.quiet, "set"):
            np.seterr(over="ignore", invalid="ignore")
            self.quiet.set = True
        try:
            action(*args)
        except Exception as error:
            self.stop(f"{type(error).__name__}: {error}")
        if self.replica is not None and self.replica.finished:
            self.cpu_s[1] = self.cpu_s[1] or time.process_time()
            self.send_log()  # the last replies: the manager finishes the run once it has them

    def drop_reply(self, sender: str, reason: str) -> None:
        """The replica dropped a reply of ``sender`` from the network (``manager.scheme.replica``)."""
        self.dropped.add(key(self.run_id, sender, "y"), reason)

    def on_control(self, sample: zenoh.Sample) -> None:
        """STOP (the manager's, or one another process that reaches the run published: the manager tells them
        apart); anything else on ``<sub>/u`` is dropped and counted."""
        data = sample.payload.to_bytes()
        try:
            kind = decode_header(data, "manager")[0]
        except ProtocolError as error:
            self.dropped.add(str(sample.key_expr), str(error), publisher(sample))
            return
        if kind != Kind.STOP:
            self.dropped.add(str(sample.key_expr), f"a {kind.name} message; only STOP is sent here", publisher(sample))
            return
        source = publisher(sample)
        self.stop(STOP_RECEIVED + (f" (from {source})" if source else ""))

    def on_liveliness(self, sample: zenoh.Sample) -> None:
        who = str(sample.key_expr).split("/")[-2]
        if sample.kind == zenoh.SampleKind.PUT:
            self.seen.add(who)
        elif who == "manager":
            self.stop("the manager is gone")


def _wait_for(endpoints: list[str], wait_s: float) -> None:
    """Until something listens at every endpoint; HostError naming the first that nothing answers on."""
    try:
        for endpoint in endpoints:
            wait_for_listener(endpoint, wait_s)
    except TimeoutError as error:
        raise HostError(f"cannot reach the run: {error}") from None


def serve(scene: Scene, name: str, connect: list[str], run_id: str | None, options: ZenohOptions,
          wait_s: float = 30.0, listen: str = "tcp/127.0.0.1:0") -> int:
    """Serve subsystem ``name`` until the run ends; return the process exit code."""
    if name not in scene.subsystems:
        raise HostError(f"scene {scene.name} has no subsystem {name!r}; expected one of {', '.join(scene.subsystems)}")
    mode = "peer"
    if run_id is None:
        # started by hand: find the run (as a client, which a router serves too), then connect to the processes
        # it exchanges with that are already in it, so that every pair that exchanges has a direct link; a
        # process that found the run through a router stays the router's client (the router forwards for it)
        _wait_for(connect, wait_s)
        with open_session(session_config(connect=connect, options=options, mode="client")) as probe:
            info = find_run(probe, scene, name, wait_s)
            through_router = any(True for _ in probe.info.routers_zid())
        run_id = info["run_id"]
        if through_router:
            mode = "client"
        else:
            via_host = endpoint_host(connect[0])  # the manager's host, where its spawned subsystems listen
            _, partners = process_scope(scene, plan_scene(scene)[0], name)
            peers = [reachable(ep, via_host) for peer, ep in info.get("endpoints", {}).items() if peer in partners]
            connect = connect + [ep for ep in peers if ep not in connect]
    _wait_for(connect, wait_s)
    listen = concrete_endpoint(listen) if mode == "peer" else None
    with open_session(session_config([listen] if listen else [], connect, options, mode), [listen] if listen else []) \
            as session:
        host = _Host(scene, name, run_id, session)
        signals = SignalNote(signal.SIGINT, signal.SIGTERM)
        entities = [
            *(session.declare_subscriber(key(run_id, peer, "y"), functools.partial(host.on_reply, peer))
              for peer in host.names if peer != name),  # the sources its replica takes replies from
            session.declare_queryable(key(run_id, name, "timing"), host.on_timing),
            session.declare_subscriber(key(run_id, name, "u"), host.on_control),
            session.declare_subscriber(key(run_id, "manager", "go"), host.on_go),
            session.declare_queryable(key(run_id, name, "ctl"), lambda query: query.reply(
                key(run_id, name, "ctl"), describe(scene, name, host.subsystem, listen, host.dropped.report()))),
            session.liveliness().declare_subscriber(key(run_id, "*", "alive"), host.on_liveliness, history=True),
            session.liveliness().declare_token(key(run_id, name, "alive")),
        ]
        others = set(host.partners) | {"manager"}
        deadline = time.monotonic() + wait_s
        while not others <= host.seen and not host.ended(signals):
            if time.monotonic() > deadline:
                host.stop(f"not connected to {', '.join(sorted(others - host.seen))} within {wait_s:g} s")
            time.sleep(0.01)
        entities.append(session.liveliness().declare_token(key(run_id, name, "ready")))
        while not host.ended(signals):
            host.finished.wait(SIGNAL_LOOK_S)
            host.send_idle_log()
        # leaving must not hang on a peer or a manager that is gone: past this limit the process exits as it is
        deadline_timer = threading.Timer(EXIT_LIMIT_S, _exit_now, (name, host.reasons[0]))
        deadline_timer.daemon = True
        deadline_timer.start()
        with host.lock:
            host.send_log()
        for entity in reversed(entities):
            entity.undeclare()
        host.replies.undeclare()
        host.log.undeclare()
    deadline_timer.cancel()
    print(printable(f"subsystem {name}: {host.reasons[0]}"), file=sys.stderr)
    return 0 if host.reasons[0].startswith(STOP_RECEIVED) else 1
