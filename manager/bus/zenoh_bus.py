"""The Zenoh bus: every subsystem in its own OS process, replies over Zenoh on loopback.

The manager listens on one TCP endpoint (a free port on 127.0.0.1 unless told otherwise), starts a
subsystem process per subsystem (or waits for the ones started by hand), checks that each loaded
the same scene and ports and is connected to every other process, then gives the start signal. Given
routers (``zencosim router``), the manager and the subsystems it starts also connect to them, and
subsystems started by hand on hosts that reach only a router join through it. Every
process runs a replica of the scheme (``manager.scheme.replica``); the manager's replica holds no subsystem:
it follows the replies, checks that every subsystem executed the commands the manager computed, and
produces the run record; it takes the replies in the batches the subsystems send it (``<sub>/log``,
see ``subsystems.process.host``), off the critical path. A recorded run taps the manager's replica,
as in process: it holds every command, reply and status of the run. A watchdog on the main thread
names any subsystem that dies or stops answering and ends the run within the scene's timeout, as the stall clock
counts it (``manager.bus.stall``: a process starved of CPU is waited for); no child process outlives the bus.
"""
from __future__ import annotations

import contextlib
import json
import os
import subprocess
import tempfile
import threading
import time
from pathlib import Path
from typing import Callable

import zenoh

from zencosim.manager.assembly import make_scheme, process_scope
from zencosim.manager.bus.backlog import Backlog
from zencosim.manager.bus.children import cpu_time_s, process_state, start_child
from zencosim.manager.bus.dropped import DroppedMessages, checked, describe, merge, publisher
from zencosim.manager.bus.router import RouterError
from zencosim.manager.bus.signals import DeferredSignals
from zencosim.manager.bus.stall import StallClock, load1
from zencosim.manager.bus.zenoh_session import (
    STOP_RECEIVED,
    ZenohOptions,
    concrete_endpoint,
    coupling_publisher,
    endpoint_host,
    free_tcp_port,
    key,
    new_run_id,
    open_session,
    reachable,
    session_config,
    wait_for_listener,
)
from zencosim.manager.plan.run_plan import Plan
from zencosim.manager.scene.load import Scene
from zencosim.manager.scheme.base import RunRecord, SubsystemFailure
from zencosim.manager.scheme.replica import Replica, Tap
from zencosim.manager.wire.protocol import Kind, ProtocolError, encode, split_messages
from zencosim.manager.wire.status import StatusReport

ROUTER_WAIT_S = 10.0  # how long the manager waits for a --connect router to listen
STARTUP_TIMEOUT_S = 30.0  # start-up fails when no spawned subsystem process has made progress for this long
STARTUP_CPU_S = 0.1  # [s] CPU time of a starting process that counts as progress (an idle Zenoh peer uses far less)
STOP_GRACE_S = 2.0  # after STOP, a child has this long to exit before it is terminated
START_DELAY_NS = 50_000_000  # the first step is released this long after the start signal (real time)
PROBE_TIMEOUT_S = 0.5  # when a run stalls, a subsystem that does not describe itself within this time is frozen
SETTLE_S = 2.0  # a failure is reported after the follower has taken what was sent before it, waiting at most this
SETTLE_QUIET_S = 0.2  # and until no batch has arrived for this long
STALL_LOOK_S = 0.5  # while the run does not advance, the stall clock reads the processes' /proc this often
EXTERNAL_STALL_FACTOR = 6.0  # a run with processes the manager did not start: the stall limit is this × manager.timeout
STALLED_S = 2.0  # the manager's watch loop (every 0.05 s) not running for this long: the manager itself stalled


class ManagerStalled(SubsystemFailure):
    """A run that failed after the manager's own process did not run for a while (stopped with SIGSTOP, starved
    of CPU): the subsystems lost its Zenoh session, so the failure they report is the manager's, and says so."""

    def __init__(self, stalled_s: float, failure: SubsystemFailure) -> None:
        self.subsystem, self.stalled_s = failure.subsystem, stalled_s
        RuntimeError.__init__(self, f"the manager did not run for {stalled_s:.1f} s (its process was stopped or "
                                    f"starved of CPU), so its Zenoh session lapsed; then {failure}")


class ZenohBus:
    """Subsystem processes joined by Zenoh sessions; use as a context manager around :meth:`drive`."""

    def __init__(self, scene: Scene, plan: Plan, options: ZenohOptions = ZenohOptions(),
                 listen: str | None = None, external: tuple[str, ...] = (), wait_external_s: float = 60.0,
                 announce: Callable[[str], None] | None = None, run_id: str | None = None,
                 routers: tuple[str, ...] = ()) -> None:
        unknown = set(external) - set(scene.subsystems)
        if unknown:
            raise ValueError(f"--external names no subsystem of scene {scene.name}: {', '.join(sorted(unknown))}")
        self.scene = scene
        self.plan = plan
        self.options = options
        self.run_id = run_id or new_run_id()
        # a free port is chosen now: the processes it spawns are told where to connect
        self.endpoint = concrete_endpoint(listen or f"{options.security.protocol}/127.0.0.1:0")
        self.protocol = self.endpoint.split("/", 1)[0]  # the processes it spawns listen on the same protocol
        self.external = tuple(external)
        self.routers = tuple(routers)
        self.wait_external_s = wait_external_s
        self.announce = announce
        self.timeout_s = scene.manager.timeout
        # processes the manager did not start may be starved of CPU on a host it cannot see: a generous limit
        self.stall_limit_s = self.timeout_s * (EXTERNAL_STALL_FACTOR if self.external else 1.0)
        self.names = [s.name for s in plan.subsystems]
        self.children: dict[str, subprocess.Popen] = {}
        self._logs = tempfile.TemporaryDirectory(prefix="zencosim-")
        self._lock = threading.Lock()
        self._joined = {name: threading.Event() for name in self.names}
        self._endpoints: dict[str, str] = {}  # where each subsystem process listens (for those started by hand)
        self._ready = {name: threading.Event() for name in self.names}
        self._sources: dict[str, str] = {}  # the publisher of each subsystem's newest batch, when Zenoh gives it
        self._lost: list[str] = []
        self._started_at = time.monotonic()  # the last time a subsystem joined or became ready (start-up progress)
        self._driving = False
        self._stop_sent = False  # whether the manager has sent its subsystems STOP (only when it closes the bus)
        self._session: zenoh.Session | None = None
        self._entities: list = []
        self.dropped = DroppedMessages()  # what the manager took off the network and dropped (manager.bus.dropped)

    # -- start-up --------------------------------------------------------------------------------
    def __enter__(self) -> "ZenohBus":
        try:
            self._open()
            self._spawn()
            self._handshake()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *_exc) -> None:
        self.close()

    def _open(self) -> None:
        for router in self.routers:
            try:
                wait_for_listener(router, ROUTER_WAIT_S)
            except TimeoutError as error:
                raise RouterError(f"cannot reach the router: {error}") from None
        self._session = open_session(session_config([self.endpoint], self.routers, self.options), [self.endpoint])
        session = self._session
        self._entities.append(session.liveliness().declare_token(key(self.run_id, "manager", "alive")))
        self._entities.append(session.declare_subscriber(key(self.run_id, "*", "log"), self._on_log))
        self._entities.append(session.liveliness().declare_subscriber(key(self.run_id, "*", "alive"), self._on_alive,
                                                                      history=True))
        self._entities.append(session.liveliness().declare_subscriber(key(self.run_id, "*", "ready"), self._on_ready,
                                                                      history=True))
        self._publishers = {name: coupling_publisher(session, key(self.run_id, name, "u")) for name in self.names}
        self._go = session.declare_publisher(key(self.run_id, "manager", "go"))

    def _on_run_query(self, query: zenoh.Query) -> None:
        info = {"run_id": self.run_id, "scene": self.scene.name, "scene_digest": self.scene.digest,
                "waiting_for": [n for n in self.names if not self._joined[n].is_set()],
                "endpoints": dict(self._endpoints)}
        query.reply(key(self.run_id, "manager", "run"), json.dumps(info).encode())

    def _on_alive(self, sample: zenoh.Sample) -> None:
        name = str(sample.key_expr).split("/")[-2]
        if name not in self._joined:
            return
        if sample.kind == zenoh.SampleKind.PUT:
            self._joined[name].set()
            self._started_at = time.monotonic()
        elif self._driving:
            self._lost.append(name)

    def _on_ready(self, sample: zenoh.Sample) -> None:
        name = str(sample.key_expr).split("/")[-2]
        if name in self._ready and sample.kind == zenoh.SampleKind.PUT:
            self._ready[name].set()
            self._started_at = time.monotonic()

    def spawn_arguments(self, name: str, listen: str | None = None, peers: tuple[str, ...] = (),
                        by_hand: bool = False) -> list[str]:
        """The ``zencosim`` arguments of subsystem ``name``'s process (``by_hand``: what a user runs on another host).

        A spawned subsystem listens on ``listen`` and connects to the manager, to ``peers``, the
        subsystems spawned before it that it exchanges values with, so that every pair of processes that
        exchanges has a direct link (and no other pair: links grow with the couplings, not with n²), and to
        the routers. One started by hand connects to the routers if there are any, else to the manager."""
        command = ["subsystem", self.scene.path, name]
        connect = (self.routers if by_hand and self.routers
                   else (reachable(self.endpoint, "127.0.0.1"), *peers, *self.routers))
        for endpoint in connect:
            command += ["--connect", endpoint]
        if listen is not None:
            command += ["--listen", listen]
        if not by_hand:
            command += ["--run-id", self.run_id]
            if self.external:  # it waits for its partners as long as the manager waits for those started by hand
                command += ["--wait", f"{self.wait_external_s:g}"]
        for override in self.scene.overrides:
            command += ["--set", override]
        if not self.options.lowlatency:
            command.append("--no-lowlatency")
        return command + self.options.security.arguments(by_hand)  # file paths: no secret on a command line

    def _spawn(self) -> None:
        spawned: dict[str, str] = {}  # name -> the endpoint the others reach it at
        for name in self.names:
            if name in self.external:
                if self.announce is not None:
                    listen = None if self.routers else f"{self.protocol}/<its-address>:<port>"
                    arguments = self.spawn_arguments(name, listen, by_hand=True)
                    command = " ".join(["zencosim"] + arguments).replace("127.0.0.1", "<this-host>")
                    self.announce(f"waiting {self.wait_external_s:g} s for subsystem {name}: on its host run\n  {command}")
                continue
            host = endpoint_host(self.endpoint)  # where the manager listens: loopback, or every interface
            listen = f"{self.protocol}/{host}:{free_tcp_port(host)}"
            log = open(Path(self._logs.name) / f"{name}.log", "wb")
            _, partners = process_scope(self.scene, self.plan, name)
            peers = tuple(endpoint for peer, endpoint in spawned.items() if peer in partners)
            self.children[name] = start_child("zencosim", self.spawn_arguments(name, listen, peers),
                                              stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT)
            log.close()
            spawned[name] = reachable(listen, "127.0.0.1")
            self._endpoints[name] = listen  # a subsystem started by hand elsewhere connects to it (subsystems.process.host)
        # a subsystem started by hand finds the run only now, with every spawned subsystem's endpoint in the
        # answer: asked earlier, it would miss one, and the two would never link directly
        self._entities.append(self._session.declare_queryable(key(self.run_id, "manager", "run"), self._on_run_query))

    def log_tail(self, name: str, lines: int = 15) -> str:
        path = Path(self._logs.name) / f"{name}.log"
        text = path.read_text(errors="replace").strip() if path.exists() else ""
        return "\n".join(text.splitlines()[-lines:])

    def _exited(self, name: str) -> SubsystemFailure | None:
        """The failure of subsystem ``name`` when the manager spawned its process and it has exited: its exit
        status and the end of its log, or, when a STOP ended it that the manager did not send, where that came from."""
        child = self.children.get(name)
        if child is None or child.poll() is None:
            return None
        tail = self.log_tail(name)
        if not self._stop_sent and f"subsystem {name}: {STOP_RECEIVED}" in tail:
            return SubsystemFailure(name, f"a STOP that the manager did not send ended its process: another process "
                                          f"that reaches the run published it on {key(self.run_id, name, 'u')} (without "
                                          f"credentials every process on the run's hosts can: docs/security.md):\n{tail}")
        return SubsystemFailure(name, f"process exited with code {child.returncode}" + (f":\n{tail}" if tail else ""))

    def _handshake(self) -> None:
        for name in self.names:
            wait_s = self.wait_external_s if name in self.external else STARTUP_TIMEOUT_S
            self._await(name, self._joined[name], wait_s, f"did not join run {self.run_id}")
            self._check_description(name)
        for name in self.names:
            self._await(name, self._ready[name], STARTUP_TIMEOUT_S,
                        f"is not connected to every other process of run {self.run_id}")

    def _await(self, name: str, event: threading.Event, wait_s: float, failing: str) -> None:
        """Wait for ``event`` of subsystem ``name``; any spawned process exiting fails (named: a subsystem that
        waits to connect to it is not the cause), and so does ``wait_s`` passing without progress: for a
        spawned subsystem, progress is another one joining or connecting, or its own process still working
        its way up (``STARTUP_CPU_S`` more CPU time: 33 processes starting on 2 cores under load take longer
        than one, but each uses CPU; one waiting for a link that never comes does not); for one started by
        hand, the wait since it began. Without progress, a spawned one's wait runs on the stall clock
        (``manager.bus.stall``: its waits for a CPU, and the manager's, are not counted)."""
        waited_from = time.monotonic()
        child = self.children.get(name)
        pids = {"manager": os.getpid(), name: child.pid} if child is not None else {}
        clock, mark = StallClock(), (waited_from, cpu_time_s(child.pid) if child is not None else 0.0)
        clock.restart(waited_from)
        clock.look(waited_from, pids)
        while not event.wait(0.05):
            failure = next(filter(None, map(self._exited, self.names)), None)
            if failure:
                raise failure
            now = time.monotonic()
            if child is None:
                stalled = now > waited_from + wait_s
            elif now - clock.last >= 1.0:
                cpu = cpu_time_s(child.pid)
                if cpu - mark[1] >= STARTUP_CPU_S or self._started_at > mark[0]:  # progress: the clock starts again
                    mark = (now, cpu)
                    clock.restart(now)
                clock.look(now, pids)
                stalled = clock.stalled_s > wait_s
            else:
                continue
            if stalled:
                tail = self.log_tail(name) if child is not None else ""
                raise SubsystemFailure(name, f"{failing} within {wait_s:g} s" + (f"; its output:\n{tail}" if tail else ""))

    def _patient(self, ask: Callable[[], bool], names: list[str]) -> str | None:
        """Call ``ask`` until it returns True, or the stall clock over the processes of ``names`` that the manager
        started (and its own) reaches ``manager.timeout`` (the limit for processes it did not start, when one
        of ``names`` is such): then the name of the one that failed it. A process starved of CPU is waited
        for."""
        clock, local = StallClock(), [name for name in names if name in self.children]
        pids = {"manager": os.getpid(), **{name: self.children[name].pid for name in local}}
        clock.restart(time.monotonic())
        clock.look(clock.last, pids)
        limit_s = self.stall_limit_s if set(names) - set(local) else self.timeout_s
        while not ask():
            clock.look(time.monotonic(), pids)
            verdict = clock.verdict(limit_s, local or names)
            if verdict is not None:
                return verdict[0]
        return None

    def _check_description(self, name: str) -> None:
        replies = []

        def ask() -> bool:
            replies.extend(r for r in self._session.get(key(self.run_id, name, "ctl"), timeout=PROBE_TIMEOUT_S)
                           if r.ok)
            return bool(replies) or self._exited(name) is not None
        self._patient(ask, [name])
        exited = self._exited(name)
        if exited is not None:
            raise exited
        if not replies:
            raise SubsystemFailure(name, "did not describe itself")
        info = json.loads(replies[0].ok.payload.to_bytes())
        if info["listen"] is not None:  # a router's client listens nowhere
            self._endpoints.setdefault(name, info["listen"])
        if info["scene_digest"] != self.scene.digest:
            raise SubsystemFailure(name, f"loaded a different scene (digest {info['scene_digest'][:12]}, manager has "
                                         f"{self.scene.digest[:12]}): start it with the same scene file and --set options")
        sub = self.plan.by_name(name)
        expected = ([[p.name, p.unit] for p in sub.inputs], [[p.name, p.unit] for p in sub.outputs])
        if (info["inputs"], info["outputs"]) != expected:
            raise SubsystemFailure(name, f"declares ports {info['inputs']} -> {info['outputs']}, expected "
                                         f"{expected[0]} -> {expected[1]}")
        identity = getattr(self.scene.subsystems[name].spec, "identity", {})
        differ = [k for k in identity if info.get("identity", {}).get(k) != identity[k]]
        if differ:
            theirs = info.get("identity", {})
            raise SubsystemFailure(name, f"its component is not the manager's: {', '.join(differ)} "
                                         + ", ".join(f"{str(theirs.get(k))[:16]} instead of {identity[k][:16]}" for k in differ)
                                         + f" ({self.scene.subsystems[name].spec.source}): give both hosts the same file")

    # -- running ---------------------------------------------------------------------------------
    def drive(self, realtime: bool = False, progress=None, status: StatusReport | None = None,
              tap: Tap | None = None, keep: bool | None = None) -> tuple[RunRecord, float]:
        """Start the run, follow it to the end; return its record and the wall-clock time [s].

        The subsystems pace their replicas (``realtime``); the manager's replica follows the batches of
        replies unpaced, and the record's timing is what the subsystems report of their own steps.
        ``tap`` sees every message of the manager's replica (a recorded run); ``keep``: its arrays in memory or
        spilled (``manager.run.execute``)."""
        scheme = make_scheme(self.scene, self.plan, False, None, progress, status, keep=keep, follower=True)
        self._replica = Replica(scheme, self.names, tap=tap, on_drop=self._drop_reply)
        self._done = threading.Event()
        self._batches = Backlog()  # (subsystem, batch of replies); None ends
        self._untaken = 0  # batches arrived that the follower has not finished with (under _untaken_lock)
        self._untaken_lock = threading.Lock()
        self._error: BaseException | None = None
        self._driving = True
        self._progress = (0, time.monotonic())
        self._stall = StallClock()  # the time the run has not advanced, less its processes' waits for a CPU
        self._stall_from = time.monotonic()  # when the run last advanced, as the watch loop saw it
        self._said_waiting = 0  # how often the wait for starved processes has been said since then
        self._stall_looked = False  # whether the stall clock has read the processes since then
        self._heard = time.monotonic()  # when the last batch of replies arrived
        self._following = False  # the follower is advancing the replica with a batch (or feeding the recorder)
        started, cpu_started = time.perf_counter(), time.process_time()
        start_unix_ns = time.time_ns() + START_DELAY_NS  # the hosts' clocks agree on it as far as they are synchronised
        if self.announce is not None:
            self.announce(f"run {self.run_id}: {len(self.names)} subsystem processes connected, starting")
        follower = threading.Thread(target=self._follow, name="zencosim-follower", daemon=True)
        follower.start()
        with self._lock:
            self._go.put(json.dumps({"start_unix_ns": start_unix_ns, "realtime": realtime}).encode())
            self._guarded(self._replica.start)
        stalled_s, tick = 0.0, time.monotonic()  # the longest the watch loop did not run, and its last run
        try:
            while not self._done.wait(0.05):
                now = time.monotonic()
                stalled_s, tick = max(stalled_s, now - tick), now
                failure = self._watchdog()
                if failure is not None:
                    with self._lock:
                        self._error = self._error or failure
                        self._done.set()
        finally:
            self._batches.put(None)
            follower.join()
        wall_s = time.perf_counter() - started - (START_DELAY_NS * 1e-9 if realtime else 0.0)
        self._driving = False
        if isinstance(self._error, SubsystemFailure) and stalled_s >= STALLED_S:  # the follower's failures too
            raise ManagerStalled(stalled_s, self._error)
        if self._error is not None:
            raise self._error
        record = self._replica.result
        record.reported_timing = self._timing_reports()
        record.dropped_messages = merge({"manager": self.dropped.report(),
                                         **{name: checked(report.pop("dropped", {})) for name, report in
                                            record.reported_timing.items()}})
        record.manager_cpu_s = time.process_time() - cpu_started
        return record, wall_s

    def _timing_reports(self) -> dict[str, dict]:
        """Every subsystem's timing of its own steps (asked together). One whose replica has not finished yet says
        so at once (on a loaded host a process may still be taking the last replies, which the manager has): it is
        asked again, as long as the processes asked are only starved of CPU (``_patient``); the stall clock starts
        again whenever a report arrives."""
        reports: dict[str, dict] = {}
        missing = list(self.names)
        while missing:
            def ask() -> bool:
                pending = {name: self._session.get(key(self.run_id, name, "timing"), timeout=PROBE_TIMEOUT_S)
                           for name in missing}
                for name, replies in pending.items():
                    answers = [reply.ok for reply in replies if reply.ok is not None]
                    if answers:
                        reports[name] = json.loads(answers[0].payload.to_bytes())
                if any(name in reports for name in missing):
                    return True
                time.sleep(0.05)
                return False
            silent = self._patient(ask, missing)
            if silent is not None:
                raise SubsystemFailure(silent, "did not report the timing of its steps")
            missing = [name for name in missing if name not in reports]
        return {name: reports[name] for name in self.names}

    def _on_log(self, sample: zenoh.Sample) -> None:
        """A batch of replies: handed to the follower thread (Zenoh's thread returns at once); one on the key
        of no subsystem of the run is dropped and counted."""
        name = str(sample.key_expr).split("/")[-2]
        if name not in self._publishers:
            self.dropped.add(str(sample.key_expr), "no subsystem of this run publishes on this key", publisher(sample))
            return
        self._heard = time.monotonic()
        source = publisher(sample)
        if source is not None:
            self._sources[name] = source
        with self._untaken_lock:
            self._untaken += 1
        self._batches.put((name, sample.payload.to_bytes()))

    def _follow(self) -> None:
        """The follower thread: advance the manager's replica with every batch, at idle priority.

        The manager's replica repeats the whole scheme (about 50 µs of Python per macro-step of
        two_mass_damped); run at normal priority on a machine with fewer free cores than processes, its
        bursts preempt a subsystem on the critical path. SCHED_IDLE (Linux; ignored elsewhere) gives
        the core to the subsystems whenever they want it; the follower still gets the time they wait
        for the network, and if it falls behind, the subsystems' batches wait for it, never lost: in memory up
        to a bound, then on disk (``manager.bus.backlog``). Measured on two_mass_damped over Zenoh:
        docs/protocol.md."""
        if hasattr(os, "SCHED_IDLE"):
            try:
                os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
            except OSError:
                pass  # a platform that refuses it: the follower runs at normal priority
        while True:
            items = self._batches.get_waiting()  # every batch there is: the replica takes them together
            batches = [item for item in items if item is not None]
            self._following = True
            with self._lock:
                if batches and self._driving and not self._done.is_set():
                    self._guarded(self._deliver_batches, batches)
            self._following = False
            with self._untaken_lock:
                self._untaken -= len(batches)
            if items[-1] is None:
                return

    def _deliver_batches(self, batches: list[tuple[str, bytes]]) -> None:
        """Hand the replica the replies of ``batches``, in order (a malformed batch: none of it is taken)."""
        taken = []
        for name, batch in batches:
            try:
                taken.append((name, split_messages(batch, f"subsystem {name}")))
            except ProtocolError as error:
                self.dropped.add(key(self.run_id, name, "log"), str(error), self._sources.get(name))
        self._replica.deliver_batches(taken)

    def _drop_reply(self, name: str, reason: str) -> None:
        """The manager's replica dropped a reply of subsystem ``name`` (``manager.scheme.replica``)."""
        self.dropped.add(key(self.run_id, name, "log"), reason, self._sources.get(name))

    def _guarded(self, action, *args) -> None:
        """Advance the manager's replica (under the lock); the end or any error finishes the run."""
        try:
            action(*args)
        except BaseException as error:
            self._error = error
        if self._error is not None or self._replica.finished:
            self._done.set()

    def _watchdog(self) -> SubsystemFailure | None:
        for name in self.names:
            failure = self._exited(name)
            if failure:
                return self._settle(failure)
        if self._lost:
            name = self._lost[0]
            return self._settle(SubsystemFailure(name, self._why_gone(name)))
        # read without the lock, which the idle-priority follower may hold while it waits for a core
        steps, missing = self._replica.steps_done, self._replica.waiting_for()
        now = time.monotonic()
        if steps != self._progress[0]:
            self._progress = (steps, now)
        advanced = max(self._progress[1], self._heard)
        # a stall is the subsystems' only when no batch arrives either and the follower has taken every batch
        # (an idle-priority follower may lag; one held up by a frozen recorder waits for it: recordings.recorder)
        if not missing or self._following or not self._batches.empty() or advanced > self._stall_from:
            self._stall_from, self._said_waiting, self._stall_looked = now, 0, False
            return None
        look_s = min(STALL_LOOK_S, self.timeout_s / 4)  # at least 4 looks within the limit; /proc is read at most
        if now - self._stall.last < look_s:  # this often (two files per thread of every process), advancing or not
            return None
        if not self._stall_looked:  # the first look without an advance: the baseline of what each used and waited
            self._stall.restart(now)
            self._stall.look(now, self._watched_pids())
            self._stall_looked = True
            return None
        self._stall.look(now, self._watched_pids())
        local = [name for name in self.names if name in self.children]
        verdict = self._stall.verdict(self.timeout_s, local)
        if verdict is not None and verdict[1] == "stalled" and self.external:  # no process here to blame
            verdict = self._stall.verdict(self.stall_limit_s, local)
        if verdict is None:
            self._say_waiting(now)
            return None
        name, why = verdict
        if why not in ("stopped", "stalled"):
            return SubsystemFailure(name, f"did not answer within the timeout of {self.timeout_s:g} s "
                                          f"(manager.timeout): {why}")
        # every replica waits when one subsystem stalls: name the ones whose process does not respond
        frozen, dropped = self._unresponsive()
        name = name if why == "stopped" else frozen[0] if frozen else missing[0]
        within = (f"the timeout of {self.timeout_s:g} s (manager.timeout)" if not self.external or why == "stopped"
                  else f"{self.stall_limit_s:g} s ({EXTERNAL_STALL_FACTOR:g} × manager.timeout: the run has "
                       "processes the manager did not start, whose CPU it cannot see)")
        return SubsystemFailure(name, f"did not answer within {within}"
                                      + (f"; its process {self._state(name) or 'does not respond'}"
                                         if why == "stopped" or name in frozen else "")
                                      + (f"; messages dropped: {dropped}" if dropped else ""))

    def _watched_pids(self) -> dict[str, int]:
        """The processes whose CPU the stall clock reads: the manager's own and the subsystem processes it
        started."""
        return {"manager": os.getpid(), **{name: child.pid for name, child in self.children.items()}}

    def _say_waiting(self, now: float) -> None:
        """Say, every ``manager.timeout`` of wall time the run has not advanced, that it waits for processes
        starved of CPU, and how much of the wait the stall limit counts."""
        waited_s = now - self._stall_from
        if self.announce is None or waited_s < self.timeout_s * (self._said_waiting + 1):
            return
        self._said_waiting = int(waited_s // self.timeout_s)
        self.announce(f"run {self.run_id}: no step for {waited_s:.1f} s; {self._stall.excused_s:.1f} s of it its "
                      f"processes waited for a CPU (load {load1():.1f} on {os.cpu_count()} CPUs): waiting; "
                      f"{self._stall.stalled_s:.1f} s of the limit of {self.stall_limit_s:g} s counted")

    def _state(self, name: str) -> str | None:
        """Why subsystem ``name``'s process does not answer, when the manager spawned it and its state says
        (``manager.bus.children.process_state``: frozen, stuck, exited)."""
        child = self.children.get(name)
        return None if child is None else process_state(child.pid)

    def _why_gone(self, name: str) -> str:
        """The reason for a subsystem whose liveliness token is gone (its Zenoh session closed or expired)."""
        if name not in self.children:
            return "its liveliness token is gone: its process ended, or froze, or its host is unreachable"
        state = self._state(name)
        if state is not None:
            return f"its process {state}, and its Zenoh session expired (liveliness token lost)"
        return "its Zenoh session is gone (liveliness token lost) although its process runs"

    def _settle(self, failure: SubsystemFailure) -> SubsystemFailure:
        """Before a process that exited or left is blamed: let the follower take the replies
        still arriving or queued (a subsystem that failed sends the reason first, in its last batch, then
        exits), and let a process that left the run exit, at most ``SETTLE_S``. The reason the follower finds
        is the run's error; else a spawned process's exit status and the end of its log; else ``failure``."""
        deadline = time.monotonic() + SETTLE_S
        child = self.children.get(failure.subsystem)
        while time.monotonic() < deadline and not self._done.is_set():
            # every batch taken to the end (one the follower holds may carry the reason: a model's error)
            quiet = self._untaken == 0 and time.monotonic() - self._heard > SETTLE_QUIET_S
            if quiet and (child is None or child.poll() is not None):
                break
            time.sleep(0.01)
        return self._exited(failure.subsystem) or failure

    def _unresponsive(self) -> tuple[list[str], str]:
        """Subsystems that do not answer a description query within ``PROBE_TIMEOUT_S`` (queried together), and
        the messages every process dropped (``manager.bus.dropped.describe``; the others' from their answers)."""
        pending = {name: self._session.get(key(self.run_id, name, "ctl"), timeout=PROBE_TIMEOUT_S)
                   for name in self.names}
        frozen, reports = [], {"manager": self.dropped.report()}
        for name, replies in pending.items():
            answers = [reply.ok for reply in replies if reply.ok is not None]
            if not answers:
                frozen.append(name)
                continue
            try:
                reports[name] = checked(json.loads(answers[0].payload.to_bytes()).get("dropped"))
            except (ValueError, AttributeError):
                pass  # not a description: nothing to add
        return frozen, describe(merge(reports))

    # -- shutdown --------------------------------------------------------------------------------
    def close(self) -> None:
        """Stop every subsystem process, then make sure none is left; close the session.

        An interrupt (SIGINT, SIGTERM: ``cli.main`` raises KeyboardInterrupt) while it waits for the processes
        kills those left at once, and the session is closed in any case, with the signals held meanwhile: an
        open session keeps Zenoh's callback threads, which are not daemons, and the process would hang at its
        exit waiting for them."""
        self._driving = False
        try:
            self._stop_children()
        except BaseException:
            for child in self.children.values():
                if child.poll() is None:
                    child.kill()
                    child.wait()
            raise
        finally:
            self._close_session()

    def _stop_children(self) -> None:
        """STOP every subsystem process; terminate, then kill, those that do not exit in ``STOP_GRACE_S``."""
        if self._session is not None:
            self._stop_sent = True
            for publisher in getattr(self, "_publishers", {}).values():
                publisher.put(encode(Kind.STOP, 0, 0))
        deadline = time.monotonic() + STOP_GRACE_S
        for child in self.children.values():
            if child.poll() is None and (process_state(child.pid) or "").startswith("is frozen"):
                child.kill()  # a stopped process cannot act on STOP or SIGTERM
            try:
                child.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                child.terminate()
                try:
                    child.wait(STOP_GRACE_S)
                except subprocess.TimeoutExpired:
                    child.kill()
                    child.wait()

    def _close_session(self) -> None:
        """Undeclare what the session declared and close it (also after a start-up cut short: only what was
        declared), with SIGINT and SIGTERM held until it is closed (in the main thread)."""
        signals = DeferredSignals() if threading.current_thread() is threading.main_thread() else None
        try:
            with signals.held() if signals is not None else contextlib.nullcontext():
                if self._session is not None:
                    for entity in reversed(self._entities):
                        entity.undeclare()
                    for publisher in getattr(self, "_publishers", {}).values():
                        publisher.undeclare()
                    if getattr(self, "_go", None) is not None:
                        self._go.undeclare()
                    self._session.close()
                    self._session = None
                self._logs.cleanup()
        finally:
            if signals is not None:
                signals.restore()
