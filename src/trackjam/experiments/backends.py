"""Where an experiment's trials run: in this process, on a local pool of processes, or on a Dask
cluster, all behind one ``concurrent.futures`` interface.

- The local pool's workers die with their parent: each one polls its parent's pid and exits when
  it changes (the parent was killed, even by SIGKILL); a SIGTERM of the parent terminates them;
  they ignore Ctrl-C, which the parent handles.
- A Dask scheduler is reached in two steps, each bounded by ``CONNECT_TIMEOUT_S``: a plain TCP
  pre-flight that reads the handshake a Dask scheduler sends first and checks that it is one
  (an HTTP or SSH server, or a silent port, would otherwise hang Dask's client or make it
  allocate a frame size read from garbage), then the client itself. The pre-flight's name
  lookup, which takes no timeout of its own, runs in a daemon thread that is waited on as long.
"""

from __future__ import annotations

import multiprocessing
import os
import re
import signal
import socket
import struct
import sys
import threading
import time
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from typing import Callable, Iterator

from trackjam.errors import ConfigError, OutputError, shortened

CONNECT_TIMEOUT_S = 5.0
LOST_CHECK_S = 2.0  # after a sweep's error: the time the scheduler is given to answer before it counts as lost
HANDSHAKE_MAX_BYTES = 1 << 20  # a scheduler's handshake is ~60 bytes; garbage reads as exabytes
PARENT_POLL_S = 0.2
# Dask schemes over TCP whose server waits for the client: a refused port is found at once, as for tcp
TCP_CARRIED = ("tls", "ws", "wss")
ADDRESS_MAX = 300  # a host name is at most 253 characters; a longer address is refused before any lookup
ADDRESS_SHOWN = 80  # characters of a --scheduler value a message shows
_ADDRESS = re.compile(r"^(?:(?P<scheme>[a-z][a-z0-9+.-]*)://)?(?P<host>\[[0-9a-fA-F:.]+\]|[^\s:/\[\]]+):(?P<port>\d{1,5})/?$")


def one_numba_thread() -> None:
    """Trials run side by side: each worker gets one numba thread, through the environment
    before numba is imported, else through ``numba.set_num_threads``. Once numba is loaded the
    environment is left alone: numba re-reads it at each compilation and refuses a thread count
    that differs from its running pool's (the in-process executor runs in such a process)."""
    numba = sys.modules.get("numba")
    if numba is None:
        os.environ["NUMBA_NUM_THREADS"] = "1"
    else:
        numba.set_num_threads(1)


def _exit_when_orphaned(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(PARENT_POLL_S)
    os._exit(1)  # the parent is gone: nobody will read this worker's result


def pool_worker_setup(parent_pid: int) -> None:
    """Initializer of a local pool worker."""
    one_numba_thread()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_exit_when_orphaned, args=(parent_pid,), name="orphan-watch", daemon=True).start()


class LocalPool(ProcessPoolExecutor):
    """A spawn-started process pool whose workers never outlive this process."""

    def __init__(self, workers: int) -> None:
        super().__init__(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                         initializer=pool_worker_setup, initargs=(os.getpid(),))

    def terminate(self) -> None:
        """Stop at once: running trials are killed, queued ones cancelled."""
        processes = list((getattr(self, "_processes", None) or {}).values())
        for p in processes:
            p.terminate()
        self.shutdown(wait=False, cancel_futures=True)
        for p in processes:
            p.join(timeout=5)


class SerialExecutor(Executor):
    """One worker: trials run in this process, one at a time, when their result is awaited."""

    def __init__(self) -> None:
        self._queue: list[tuple[Future, Callable, tuple]] = []

    def submit(self, fn, /, *args, **kwargs) -> Future:
        f: Future = Future()
        self._queue.append((f, fn, args))
        return f

    def run_next(self) -> None:
        f, fn, args = self._queue.pop(0)
        if f.set_running_or_notify_cancel():
            try:
                f.set_result(fn(*args))
            except BaseException as err:  # handed to the caller through the future
                f.set_exception(err)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        for f, _, _ in self._queue:
            f.cancel()
        self._queue.clear()


@contextmanager
def _sigterm_exits() -> Iterator[None]:
    """Inside, SIGTERM raises SystemExit(143), so the pool is terminated on the way out."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        raise SystemExit(128 + signum)

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextmanager
def open_executor(workers: int | None, scheduler: str | None) -> Iterator[tuple[Executor, int]]:
    """The executor and how many trials to keep in flight. With ``scheduler`` the connection is
    made (or refused with a one-line ConfigError) on entry, before the caller writes anything."""
    if scheduler:
        yield from _dask_executor(scheduler)
        return
    n = workers or os.cpu_count() or 1
    if n == 1:
        ex = SerialExecutor()
        try:
            yield ex, 2
        finally:
            ex.shutdown()
        return
    pool = LocalPool(n)
    with _sigterm_exits():
        try:
            yield pool, 2 * n
        except BrokenProcessPool:
            # a worker killed from outside (the kernel's out-of-memory killer, a `kill -9`): it was an
            # 86-line traceback, exit status 1
            pool.terminate()
            raise OutputError("a worker process of the pool ended abruptly (killed from outside, perhaps by the system "
                              "for lack of memory, or failing as it started: see above); the trials written are "
                              "intact: run the same command again to resume, with fewer --workers if memory is "
                              "short") from None
        except BaseException:
            pool.terminate()
            raise
    pool.shutdown(wait=True)


def parse_scheduler_address(address: str) -> tuple[str, str, int]:
    """(scheme, host, port) of ``[scheme://]HOST:PORT``, or a one-line ConfigError."""
    m = _ADDRESS.match(address.strip()) if len(address) <= ADDRESS_MAX else None
    if m is None or not 0 < int(m["port"]) < 65536:
        raise ConfigError(f"--scheduler {shortened(address, ADDRESS_SHOWN)!r}: not an address of the form tcp://HOST:PORT")
    try:  # what the name lookup does first; its UnicodeError (an empty label, one past 63 characters) is no OSError
        m["host"].strip("[]").encode("idna")
    except UnicodeError as err:
        reason = str(err).rpartition("UnicodeError: ")[2].rstrip(")") or "idna"
        raise ConfigError(f"--scheduler {address!r}: host {m['host']!r} is not a valid host name ({reason})") from None
    scheme = m["scheme"] or "tcp"
    if scheme not in ("tcp", *TCP_CARRIED):
        # ucx:// without ucx-py left a half-built client whose exit hung 10 s and printed a traceback
        raise ConfigError(f"--scheduler {address!r}: scheme {scheme}:// is not supported; use tcp://, tls://, ws:// or wss://")
    return scheme, m["host"].strip("[]"), int(m["port"])


def _read_exactly(sock: socket.socket, n: int, deadline: float) -> bytes:
    data = b""
    while len(data) < n:
        sock.settimeout(max(deadline - time.monotonic(), 0.01))
        chunk = sock.recv(min(n - len(data), 1 << 16))
        if not chunk:
            raise ConnectionError("the connection was closed")
        data += chunk
    return data


def check_dask_scheduler(address: str, timeout_s: float = CONNECT_TIMEOUT_S) -> str:
    """Refuse, with one line and within about ``timeout_s``, an address that is not a reachable
    Dask scheduler speaking plain TCP. Returns the IP address (as ``host``, an IPv6 one in
    brackets) that answered, so that the client need not look the name up again."""
    scheme, host, port = parse_scheduler_address(address)
    where = f"the Dask scheduler at {address}"
    deadline = time.monotonic() + timeout_s
    try:
        sock = _connect(_look_up(address, host, port, timeout_s), timeout_s)
    except OSError as err:
        raise ConfigError(f"cannot reach {where} within {timeout_s:g} s: {err.strerror or err}") from None
    ip = sock.getpeername()[0]
    ip = f"[{ip}]" if ":" in ip else ip
    if scheme in TCP_CARRIED:  # its server speaks second: only the connection is checked
        sock.close()
        return ip
    with sock:
        try:
            head = _read_exactly(sock, 8, deadline)
            (size,) = struct.unpack("<Q", head)
            if not 0 < size <= HANDSHAKE_MAX_BYTES:
                raise ValueError(f"it sent {head!r}")
            _check_handshake(_read_exactly(sock, size, deadline))
        except (TimeoutError, socket.timeout):
            raise ConfigError(f"{address} accepted the connection but sent no Dask handshake within "
                              f"{timeout_s:g} s: not a Dask scheduler?") from None
        except (OSError, ValueError) as err:
            raise ConfigError(f"{address} does not speak Dask's protocol ({err}): not a Dask scheduler?") from None
    return ip


def _look_up(address: str, host: str, port: int, timeout_s: float) -> list[tuple]:
    """``socket.getaddrinfo``'s addresses of ``host`` as ``socket.create_connection`` asks for them,
    or what it raised (an OSError for an unknown name), within ``timeout_s``: the lookup runs in a
    daemon thread, since it takes no timeout (a slow or unreachable DNS server held the pre-flight
    as long as it liked); one that does not answer in time is a one-line ConfigError and is left
    to finish alone."""
    answer: list = []

    def look_up() -> None:
        try:
            answer.append(socket.getaddrinfo(host, port, 0, socket.SOCK_STREAM))
        except Exception as err:  # noqa: BLE001 - raised again in the caller's thread, as before
            answer.append(err)

    thread = threading.Thread(target=look_up, name="scheduler-lookup", daemon=True)
    thread.start()
    thread.join(timeout_s)
    if not answer:
        raise ConfigError(f"--scheduler {address!r}: the name lookup of host {host!r} did not answer within "
                          f"{timeout_s:g} s (a slow or unreachable DNS server?); try again, or give its IP address")
    if isinstance(answer[0], Exception):
        raise answer[0]
    return answer[0]


def _connect(addresses: list[tuple], timeout_s: float) -> socket.socket:
    """A socket connected to the first of ``addresses`` (getaddrinfo's) that accepts within
    ``timeout_s``, else the last one's OSError: what ``socket.create_connection`` does once it
    has looked the name up."""
    error = OSError("getaddrinfo returns an empty list")
    for family, kind, proto, _, sockaddr in addresses:
        sock = None
        try:
            sock = socket.socket(family, kind, proto)
            sock.settimeout(timeout_s)
            sock.connect(sockaddr)
            return sock
        except OSError as err:
            error = err
            if sock is not None:
                sock.close()
    raise error


def _check_handshake(payload: bytes) -> None:
    import msgpack
    from distributed.protocol.utils import unpack_frames

    try:
        info = msgpack.loads(unpack_frames(payload)[0], raw=False)
    except Exception as err:  # whatever garbage does to the decoders
        raise ValueError(f"an undecodable handshake: {type(err).__name__}") from None
    if not (isinstance(info, dict) and "python" in info):
        raise ValueError("a handshake without the scheduler's Python version")


def _discard(client) -> None:
    """Close a client whose construction failed, or whose sweep is over (its scheduler perhaps
    lost: ``close`` then raises or waits, bounded here by CONNECT_TIMEOUT_S), so that nothing is
    left for its ``__del__``: its loop thread stopped and its status ``closed`` (``__del__``
    then does nothing)."""
    try:
        client.close(timeout=CONNECT_TIMEOUT_S)
    except Exception:  # noqa: BLE001 - a half-built client may lack what close() reads
        pass
    try:
        client.status = "closed"
        client._loop_runner.stop()
    except Exception:  # noqa: BLE001 - failed before its loop runner existed
        pass


def _dask_executor(address: str) -> Iterator[tuple[Executor, int]]:
    try:
        from distributed import Client
    except ImportError:
        raise ConfigError("--scheduler needs dask.distributed, the dask extra: pip install \".[dask]\" from the trackjam "
                          "checkout") from None
    ip = check_dask_scheduler(address, CONNECT_TIMEOUT_S)  # the timeout as it is now (a test makes it short)
    scheme, _, port = parse_scheduler_address(address)
    # plain TCP connects to the IP address the pre-flight reached: the client's own name lookup
    # took no timeout of ours; TLS and websockets keep the name their certificates are for
    target = f"tcp://{ip}:{port}" if scheme == "tcp" else address
    if scheme == "tls":
        from distributed.security import Security

        # else Client fails with a TypeError and its half-built self hangs 10 s at exit
        if Security().get_connection_args("client").get("ssl_context") is None:
            raise ConfigError(f"--scheduler {address}: TLS needs a client certificate in Dask's configuration "
                              "(distributed.comm.tls.*); none is set")
    # built in two steps to keep a handle on it: a constructor that fails (ws:// to an HTTP
    # server, wss:// to a port that hangs up) leaves a half-built client whose __del__, at exit,
    # waited 10 s and printed a traceback ("Exception ignored in: <function Client.__del__>")
    client = Client.__new__(Client)
    try:
        client.__init__(target, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except Exception as err:  # noqa: BLE001 - Dask's own refusals vary: a TypeError for TLS without a security configuration
        _discard(client)
        msg = " ".join(str(err).split()) or type(err).__name__
        raise ConfigError(f"cannot reach the Dask scheduler at {address}: {msg}") from None
    quiet = _quiet_client_log()
    try:
        if not client.scheduler_info().get("workers"):  # else the sweep would wait without a word
            print(f"trackjam: the Dask scheduler at {address} has no workers yet; the trials wait for one",
                  file=sys.stderr, flush=True)
        yield client.get_executor(), 1 << 30  # the scheduler balances the load: submit everything
    except Exception as err:  # noqa: BLE001 - what Dask raises on a lost connection varies (CancelledError, CommClosedError)
        if _reachable(address):
            raise  # a trial's own error, or a failure of ours: not the scheduler's
        raise OutputError(f"--scheduler {address}: lost the Dask scheduler ({type(err).__name__}); the trials "
                          "written are intact: run the same command again to resume") from None
    finally:
        _discard(client)
        quiet()


def _reachable(address: str) -> bool:
    """The scheduler at ``address`` still answers (a short pre-flight, :func:`check_dask_scheduler`)."""
    try:
        check_dask_scheduler(address, LOST_CHECK_S)
        return True
    except ConfigError:
        return False


def _quiet_client_log() -> Callable[[], None]:
    """Keep Dask's client from logging its reconnection attempts, tracebacks and all, while a sweep
    runs: a lost scheduler is said in one line of ours. Returns what restores the log level."""
    import logging

    log = logging.getLogger("distributed.client")
    level = log.level
    log.setLevel(logging.CRITICAL)
    return lambda: log.setLevel(level)
