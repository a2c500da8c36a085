"""What the fault tests share: a tiny rig of real processes, its counters, /proc samples, a delay proxy.

Every process is `python -m services.cli ...` in a session (process group) of its own, started
with one numba thread and the same environment (so every worker loads the kernels `ig compile`
cached once for the suite, tests/faults/conftest.py). `RigProcs.stop_all` (called by every
fixture's finalizer) ends each group with SIGTERM, then SIGKILL: no test leaves a process behind,
whatever it asserted.
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import itertools
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import grpc

from ig.v1 import (
    compositor_pb2,
    compositor_pb2_grpc,
    host_pb2,
    host_pb2_grpc,
    worker_pb2,
    worker_pb2_grpc,
)
from services.demo import local_rig
from services.rig.grpc_util import check_health, make_channel
from services.rig.options import RenderOptions
from services.rig.rigfile import Rig, SyncSpec, TlsSpec, default_rig_path, load_rig, rig_toml

ROOT = Path(__file__).resolve().parents[2]
SCENE = Path(__file__).resolve().parent / "scene.json"

#: Longest wait for anything that should happen "soon" on a loaded 2-core machine, seconds: only
#: there to fail a hung test, never a measure of speed.
PATIENCE_S = 60.0

#: What every worker of the suite renders: one sample per pixel, no atmosphere (tiny, fast frames).
OPTIONS = RenderOptions(samples="centre", haze=False, clouds=False)


def env() -> dict[str, str]:
    """The environment of every process of the suite: one numba thread each (five processes
    share two cores), and the caller's IG_CACHE_DIR (the compiled kernels) if it set one."""
    return {**os.environ, "NUMBA_NUM_THREADS": "1", "PYTHONUNBUFFERED": "1"}


def write_rig(path: Path, *, width: int = 64, height: int = 48, sync: SyncSpec | None = None,
              tls: TlsSpec | None = None, addresses: dict[str, str] | None = None) -> Rig:
    """The default three-channel rig at width x height, on free 127.0.0.1 ports (or addresses:
    "host", "compositor" and channel name -> host:port), written to path; returns it."""
    rig = local_rig(load_rig(default_rig_path()).with_size(width, height))
    rig = replace(rig, render=OPTIONS, sync=sync or SyncSpec(), tls=tls or TlsSpec())
    if addresses:
        rig = replace(rig, host_address=addresses["host"], compositor_address=addresses["compositor"],
                      channels=tuple(replace(ch, address=addresses[ch.name]) for ch in rig.channels))
    path.write_text(rig_toml(rig))
    return load_rig(path)


def write_rig_via(path: Path, rig: Rig, *, host_address: str) -> Path:
    """The same rig with another host address (a proxy's), for one worker: same channels."""
    path.write_text(rig_toml(replace(rig, host_address=host_address)))
    return path


# --- processes ------------------------------------------------------------------------------
class RigProcs:
    """The processes of one test: started, signalled, and always stopped (stop_all).

    Args:
        log_dir: each process's output goes to LOG_DIR/NAME.log.
        prefix: argv in front of `python -m services.cli` (e.g. `ip netns exec NS`).
    """

    def __init__(self, log_dir: Path) -> None:
        self.log_dir = log_dir
        self.procs: dict[str, subprocess.Popen] = {}
        self._logs: list[Any] = []

    def start(self, name: str, argv: list[str], *, prefix: tuple[str, ...] = ()) -> subprocess.Popen:
        """`ig ARGV...` as name (a name used before is replaced: its log is appended to)."""
        self.log_dir.mkdir(parents=True, exist_ok=True)
        log = open(self.log_dir / f"{name}.log", "a")  # noqa: SIM115  (closed by stop_all)
        self._logs.append(log)
        log.write(f"--- {time.strftime('%H:%M:%S')} {' '.join(argv)}\n")
        log.flush()
        proc = subprocess.Popen([*prefix, sys.executable, "-m", "services.cli", *argv], stdout=log,
                                stderr=subprocess.STDOUT, env=env(), cwd=ROOT, start_new_session=True)
        self.procs[name] = proc
        return proc

    def signal(self, name: str, signum: int) -> None:
        """Send signum to name's process group (nothing if it has exited)."""
        proc = self.procs[name]
        if proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signum)

    def kill(self, name: str) -> int:
        """SIGKILL name and reap it; its exit code."""
        self.signal(name, signal.SIGKILL)
        return self.procs[name].wait(timeout=PATIENCE_S)

    def terminate(self, name: str, timeout_s: float = PATIENCE_S) -> int:
        """SIGTERM name and wait for it (SIGKILL after timeout_s); its exit code."""
        self.signal(name, signal.SIGCONT)  # a stopped process cannot act on SIGTERM
        self.signal(name, signal.SIGTERM)
        try:
            return self.procs[name].wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            return self.kill(name)

    def wait(self, name: str, timeout_s: float = PATIENCE_S) -> int | None:
        """name's exit code once it exits, None if still running after timeout_s."""
        try:
            return self.procs[name].wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            return None

    def pid(self, name: str) -> int:
        return self.procs[name].pid

    def log(self, name: str) -> str:
        path = self.log_dir / f"{name}.log"
        return path.read_text(errors="replace") if path.exists() else ""

    def logs_tail(self, lines: int = 20) -> str:
        """The end of every log, for an assertion message."""
        return "\n".join(f"== {n} ==\n" + "\n".join(self.log(n).splitlines()[-lines:]) for n in self.procs)

    def stop_all(self, timeout_s: float = 15.0) -> None:
        """SIGCONT + SIGTERM every group still running, then SIGKILL whatever is left after timeout_s."""
        for name in self.procs:
            self.signal(name, signal.SIGCONT)
            self.signal(name, signal.SIGTERM)
        deadline = time.monotonic() + timeout_s
        for name, proc in self.procs.items():
            try:
                proc.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                self.signal(name, signal.SIGKILL)
                proc.wait()
        for f in self._logs:
            f.close()
        self._logs.clear()


def start_rig(procs: RigProcs, rig_path: Path, rig: Rig, out: Path, *, host_args: tuple[str, ...] = (),
              compositor_args: tuple[str, ...] = (), worker_args: tuple[str, ...] = (),
              worker_rigs: dict[str, Path] | None = None, host: bool = True) -> None:
    """Compositor, one worker per channel (rig_path, or worker_rigs[channel]) and the host, in that
    order; returns once every one of them is SERVING."""
    procs.start("compositor", ["compositor", "--rig", str(rig_path), "--out", str(out), "--exr-every", "0",
                               *compositor_args])
    for ch in rig.channels:
        path = (worker_rigs or {}).get(ch.name, rig_path)
        procs.start(ch.name, ["worker", "--rig", str(path), "--channel", ch.name, "--scene", str(SCENE),
                              *worker_args])
    if host:
        procs.start("host", ["host", "--rig", str(rig_path), *host_args])
    for name, address in addresses(rig).items():
        if name in procs.procs:
            wait_serving(address, procs.procs[name], procs)


def addresses(rig: Rig) -> dict[str, str]:
    """Process name -> address: "host", "compositor" and each channel's worker."""
    return {"host": rig.host_address, "compositor": rig.compositor_address,
            **{ch.name: ch.address for ch in rig.channels}}


def wait_serving(address: str, proc: subprocess.Popen, procs: RigProcs | None = None,
                 timeout_s: float = 180.0) -> None:
    """Return once the process at address says SERVING; fail the test if it exits or hangs."""
    deadline = time.monotonic() + timeout_s
    status = "UNREACHABLE"
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise AssertionError(f"{address}: exited with {proc.returncode} before SERVING\n"
                                 f"{procs.logs_tail() if procs else ''}")
        status = health(address)
        if status == "SERVING":
            return
        time.sleep(0.1)
    raise AssertionError(f"{address}: {status} after {timeout_s} s\n{procs.logs_tail() if procs else ''}")


def health(address: str) -> str:
    """The health status name, or UNREACHABLE."""
    try:
        return check_health(address, timeout_s=2.0)
    except grpc.RpcError:
        return "UNREACHABLE"


def poll(predicate: Callable[[], Any], *, timeout_s: float = PATIENCE_S, every_s: float = 0.1,
         what: str = "condition") -> Any:
    """predicate()'s first truthy value, polled every every_s; AssertionError after timeout_s."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(every_s)


# --- counters -------------------------------------------------------------------------------
def host_status(address: str) -> host_pb2.GetHostStatusResponse:
    with make_channel(address) as ch:
        return host_pb2_grpc.HostServiceStub(ch).GetHostStatus(host_pb2.GetHostStatusRequest(), timeout=5)


def compositor_report(address: str) -> dict:
    """GetCompositorReport's report document."""
    with make_channel(address) as ch:
        resp = compositor_pb2_grpc.CompositorServiceStub(ch).GetCompositorReport(
            compositor_pb2.GetCompositorReportRequest(), timeout=5)
    return json.loads(resp.report_json)


def worker_status(address: str) -> worker_pb2.GetWorkerStatusResponse:
    with make_channel(address) as ch:
        return worker_pb2_grpc.ChannelWorkerServiceStub(ch).GetWorkerStatus(worker_pb2.GetWorkerStatusRequest(),
                                                                            timeout=5)


def final_report(out: Path) -> dict:
    """The report.json of the newest run under out: OUT/latest/report.json (run directories),
    else OUT/report.json (one run per output directory, before run identity); {} if neither."""
    for path in (out / "latest" / "report.json", out / "report.json"):
        if path.exists():
            return json.loads(path.read_text())
    return {}


def raw_call(address: str, method: str, payload: bytes, *, stream: bool = False,
             timeout_s: float = 5.0) -> tuple[str, str]:
    """Send payload (any bytes, serialised by nobody) to method ("/ig.v1.HostService/AckFrame");
    (status code name, details). A stream's first message counts as OK."""
    with make_channel(address) as ch:
        kind = ch.unary_stream if stream else ch.unary_unary
        call = kind(method, request_serializer=lambda b: b, response_deserializer=lambda b: b)
        try:
            if stream:
                for _ in call(payload, timeout=timeout_s):
                    break
            else:
                call(payload, timeout=timeout_s)
            return "OK", ""
        except grpc.RpcError as exc:
            return exc.code().name, exc.details() or ""


class CompositeWatcher:
    """A WatchComposites stream on a thread: (frame_number, run_id, composite_time) of every
    composite, and the time (monotonic) each arrived. Follows the compositor across runs and
    restarts of its stream."""

    def __init__(self, address: str) -> None:
        self.address = address
        self.composites: list[tuple[int, str, float]] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                with make_channel(self.address) as ch:
                    stream = compositor_pb2_grpc.CompositorServiceStub(ch).WatchComposites(
                        compositor_pb2.WatchCompositesRequest(watcher="fault-suite"), timeout=3600)
                    done = threading.Event()
                    threading.Thread(target=self._cancel_on_stop, args=(stream, done), daemon=True).start()
                    try:
                        for c in stream:
                            with self._lock:
                                self.composites.append((c.frame_number, c.run_id, time.monotonic()))
                    finally:
                        done.set()
            except grpc.RpcError:
                pass
            self._stop.wait(0.2)

    def _cancel_on_stop(self, stream: Any, done: threading.Event) -> None:
        while not done.is_set():
            if self._stop.wait(0.2):
                stream.cancel()
                return

    def snapshot(self) -> list[tuple[int, str, float]]:
        with self._lock:
            return list(self.composites)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)


# --- /proc ------------------------------------------------------------------------------------
def rss_mib(pid: int) -> float:
    """Resident set size of pid, MiB (VmRSS of /proc/PID/status)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    raise ValueError(f"/proc/{pid}/status: no VmRSS")


def open_fds(pid: int) -> int:
    """Open file descriptors of pid (entries of /proc/PID/fd)."""
    return len(os.listdir(f"/proc/{pid}/fd"))


class ProcSampler:
    """RSS (MiB) and open fds of named pids every every_s seconds on a thread."""

    def __init__(self, pids: dict[str, int], every_s: float = 1.0) -> None:
        self.pids = pids
        self.every_s = every_s
        self.samples: dict[str, list[tuple[float, float, int]]] = {n: [] for n in pids}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            for name, pid in self.pids.items():
                with contextlib.suppress(OSError, ValueError):
                    self.samples[name].append((time.monotonic(), rss_mib(pid), open_fds(pid)))
            self._stop.wait(self.every_s)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)


def quarters(values: list[float]) -> tuple[float, float]:
    """Medians of the first and the last quarter of values."""
    q = max(1, len(values) // 4)
    first, last = sorted(values[:q]), sorted(values[-q:])
    return first[len(first) // 2], last[len(last) // 2]


def tree_hashes(root: Path) -> dict[str, str]:
    """sha256 of every file under root, by relative path."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


# --- a TCP proxy that delays one direction --------------------------------------------------
@dataclass
class _Chunk:
    due: float
    data: bytes


class DelayProxy:
    """Forwards 127.0.0.1:port to target, holding every byte going client -> target for `delay_s`
    seconds (changeable while it runs; order is kept). Runs an asyncio loop on its own thread.

    Args:
        target: host:port to forward to.
        delay_s: initial delay of the client -> target direction, seconds.
    """

    def __init__(self, target: str, delay_s: float = 0.0) -> None:
        self.target_host, _, port = target.rpartition(":")
        self.target_port = int(port)
        self.delay_s = delay_s
        self.bytes_forwarded = 0
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._server: asyncio.base_events.Server | None = None
        self._tasks: set[asyncio.Task] = set()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()
        if not self._ready.wait(10):
            raise RuntimeError("proxy did not start")
        assert self._server is not None
        self.port = self._server.sockets[0].getsockname()[1]
        self.address = f"127.0.0.1:{self.port}"

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)

        async def start() -> None:
            self._server = await asyncio.start_server(self._client, "127.0.0.1", 0)
            self._ready.set()

        self._loop.run_until_complete(start())
        try:
            self._loop.run_forever()
        finally:
            self._loop.close()  # its self-pipe sockets too: an unclosed loop is a ResourceWarning

    async def _client(self, c_reader: asyncio.StreamReader, c_writer: asyncio.StreamWriter) -> None:
        try:
            t_reader, t_writer = await asyncio.open_connection(self.target_host, self.target_port)
        except OSError:
            c_writer.close()
            return
        task = asyncio.current_task()
        assert task is not None
        self._tasks.add(task)
        try:
            await asyncio.gather(self._pipe(c_reader, t_writer, delayed=True),
                                 self._pipe(t_reader, c_writer, delayed=False), return_exceptions=True)
        finally:
            self._tasks.discard(task)
            for w in (c_writer, t_writer):
                w.close()

    async def _pipe(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, *, delayed: bool) -> None:
        queue: asyncio.Queue[_Chunk | None] = asyncio.Queue()

        async def send() -> None:
            while (chunk := await queue.get()) is not None:
                wait = chunk.due - self._loop.time()
                if wait > 0:
                    await asyncio.sleep(wait)
                writer.write(chunk.data)
                self.bytes_forwarded += len(chunk.data)
                await writer.drain()
            writer.close()

        sender = asyncio.ensure_future(send())
        last_due = 0.0
        try:
            while data := await reader.read(65536):
                last_due = max(last_due, self._loop.time() + (self.delay_s if delayed else 0.0))
                queue.put_nowait(_Chunk(last_due, data))
        finally:
            queue.put_nowait(None)
            with contextlib.suppress(Exception):
                await sender

    def close(self) -> None:
        async def shut() -> None:
            if self._server is not None:
                self._server.close()
            tasks = list(self._tasks)
            for t in tasks:
                t.cancel()
            # Let the cancelled connections run their finally clauses (closing both sockets).
            await asyncio.gather(*tasks, return_exceptions=True)

        asyncio.run_coroutine_threadsafe(shut(), self._loop).result(timeout=10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=10)


@contextlib.contextmanager
def sampled(pids: dict[str, int], every_s: float = 1.0) -> Iterator[ProcSampler]:
    sampler = ProcSampler(pids, every_s)
    try:
        yield sampler
    finally:
        sampler.close()


def published_intervals(address: str, seconds: float, every_s: float = 0.05) -> list[float]:
    """Seconds between successive frames the host published, watching GetHostStatus for seconds
    (an interval shorter than every_s is seen as its polling period)."""
    times: list[float] = []
    last = host_status(address).frames_published
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        n = host_status(address).frames_published
        if n != last:
            now = time.monotonic()
            times.extend([now] * (n - last))
            last = n
        time.sleep(every_s)
    return [b - a for a, b in itertools.pairwise(times)]


def record(test: str, **values: Any) -> None:
    """Keep a test's measured numbers in out/faults/measured.json (docs/faults.md is filled from it)."""
    path = ROOT / "out" / "faults" / "measured.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    doc = json.loads(path.read_text()) if path.exists() else {}
    doc.setdefault(test, {}).update(values)
    doc[test]["when"] = time.strftime("%Y-%m-%d %H:%M:%S")
    path.write_text(json.dumps(doc, indent=2, sort_keys=True, default=str) + "\n")
