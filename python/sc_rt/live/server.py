"""``sc-rt live``: an LCM bus served on a Foxglove WebSocket server.

The server is the Foxglove SDK's (``foxglove.start_server``), which speaks
the subprotocol ``foxglove.sdk.v1``: what Foxglove and PlotJuggler's
Foxglove Bridge client offer (docs/LOGS.md, "Live"). Each client has a
bounded queue in the SDK; when a client reads too slowly its oldest
messages are dropped (``backlog``), never the bus's.

Nothing is decoded while no client listens: the LCM subscription then
covers the configuration channels and the runs' start records only (sent
once at a run's start: the pointing bound needs the run's
``controller_config_t``, the law's telemetry names come from the start
record on ``SCRT_HIL_START``, which ``sc-rt hil --live`` sends before any
client can have subscribed); the first
subscription of a client opens the whole bus, the last unsubscription
closes it again (the SDK's server listener callbacks, ``on_subscribe`` and
``on_unsubscribe``, applied by the loop's thread). The messages LCM holds are taken in batches, each
channel's decoded at once.
"""

from __future__ import annotations

import logging
import os
import select
import threading
import time
from collections import Counter
from collections.abc import Callable
from typing import Any

import foxglove

from sc_rt.live.bridge import Bridge
from sc_rt.live.ratelimit import DEFAULT_RATE_HZ
from sc_rt.wire.auth import open_bus

__all__ = ["LiveServer", "LiveError", "DEFAULT_PORT", "QUEUE_CAPACITY"]

#: Foxglove's default WebSocket port
DEFAULT_PORT = 8765
#: messages LCM may hold for the loop (a burst of a lockstep run)
QUEUE_CAPACITY = 10000
#: every bench's configuration and start record channels (any prefix): listened to even with no client
CONFIG_CHANNELS = ".*SCRT_(CONFIG|HIL_START)"


class LiveError(RuntimeError):
    """The server cannot start (one line naming the option)."""


class _Listener:
    """The SDK's server listener: which (client, channel) subscriptions exist."""

    def __init__(self, wake: Callable[[], None]):
        self.subs: set[tuple[int, int]] = set()
        self.new: set[int] = set()  # channels subscribed to since the loop last looked
        self.lock = threading.Lock()
        self.wake = wake

    def on_subscribe(self, client: Any, channel: Any) -> None:
        with self.lock:
            self.subs.add((client.id, channel.id))
            self.new.add(channel.id)
        self.wake()

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        with self.lock:
            self.subs.discard((client.id, channel.id))
        self.wake()


class LiveServer:
    """The bus at ``url`` served on ``host:port``.

    Parameters
    ----------
    url : str
        The LCM URL.
    prefix : str
        The bench's channel prefix (its channels are advertised at once).
    host : str
        The address to listen on.
    port : int
        The TCP port (0: a free one, ``port`` after ``start``).
    max_rate : float
        [Hz] cap of the periodic channels (0: every message).
    rates : dict, optional
        {channel: Hz} per channel.
    auth_key : bytes, optional
        The bus key (wire/auth.py): only verified messages are served.
    backlog : int
        Messages the SDK queues per client before it drops the oldest.
    ros2 : bool
        Also the ROS 2 twin of each topic (``/ros2/<topic>``, for PlotJuggler: ros2.py).
    """

    def __init__(self, url: str, *, prefix: str = "", host: str = "127.0.0.1", port: int = DEFAULT_PORT,
                 max_rate: float = DEFAULT_RATE_HZ, rates: dict[str, float] | None = None,
                 auth_key: bytes | None = None, backlog: int = 1024, ros2: bool = False):
        self.url, self.prefix, self.host, self.port = url, prefix, host, port
        self.max_rate, self.rates, self.key, self.backlog, self.ros2 = max_rate, rates, auth_key, backlog, ros2
        self.counters: Counter = Counter()
        self.server: Any = None
        self.lc: Any = None
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_w, False)
        self.listener = _Listener(self._wake)
        self._sub_all: Any = None
        self._sub_cfg: Any = None
        self._closed = False
        self._pending: list[tuple[str, bytes, int]] = []
        self._handled = threading.Condition()

    def _wake(self) -> None:
        if self._closed:
            return
        try:
            os.write(self._wake_w, b"x")
        except (BlockingIOError, OSError):
            pass  # already awake

    def start(self) -> LiveServer:
        """Bind the server, then open the bus (LiveError, RuntimeError: one line)."""
        logging.getLogger("foxglove").setLevel(logging.ERROR)  # a refused client is no news for the run
        self.ctx = foxglove.Context()
        self.bridge = Bridge(self.ctx, self.prefix, self.max_rate, self.rates, ros2=self.ros2)
        try:
            self.server = foxglove.start_server(name="sc-rt live", host=self.host, port=self.port,
                                                context=self.ctx, server_listener=self.listener,
                                                message_backlog_size=self.backlog)
        except Exception as e:  # the SDK raises its own error types
            why = str(e).strip().splitlines()[-1] if str(e).strip() else type(e).__name__
            raise LiveError(f"--port {self.port}: cannot serve on {self.host}:{self.port}: {why}") from None
        self.port = self.server.port
        try:
            self.lc = open_bus(self.url, self.key, self.counters)
            self._sub_cfg = self._subscribe(CONFIG_CHANNELS)
        except BaseException:
            self.server.stop()
            raise
        return self

    @property
    def ws_url(self) -> str:
        """The server's address for a client."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"

    def _subscribe(self, regex: str) -> Any:
        sub = self.lc.subscribe(regex, self._on_message if regex == CONFIG_CHANNELS else self._on_any)
        sub.set_queue_capacity(QUEUE_CAPACITY)
        return sub

    def _on_message(self, channel: str, data: bytes) -> None:
        self._pending.append((channel, data, time.time_ns()))

    def _on_any(self, channel: str, data: bytes) -> None:
        if not channel.endswith(("SCRT_CONFIG", "SCRT_HIL_START")):  # those come through their own subscription
            self._pending.append((channel, data, time.time_ns()))

    def wait_received(self, n: int, timeout: float) -> bool:
        """Wait until the bridge has received ``n`` messages (False after ``timeout`` seconds)."""
        with self._handled:
            return self._handled.wait_for(lambda: self.bridge.stats["received"] >= n, timeout)

    def _receive(self, fd: int, most: int = 2000) -> None:
        """Every message LCM has for us (up to ``most``), then the bridge's work on them at once."""
        for _ in range(most):
            self.lc.handle_timeout(0)
            if not select.select([fd], [], [], 0)[0]:
                break
        batch, self._pending = self._pending, []
        if batch:
            self.bridge.handle(batch)
            with self._handled:
                self._handled.notify_all()

    def _sync(self) -> None:
        """The whole bus while a client subscribes to anything, else the configurations and start
        records only (their subscription stays: neither is lost to the switch)."""
        with self.listener.lock:
            active = bool(self.listener.subs)
            new, self.listener.new = self.listener.new, set()
        if active and self._sub_all is None:
            self._sub_all = self._subscribe(".*")
        elif not active and self._sub_all is not None:
            self.lc.unsubscribe(self._sub_all)
            self._sub_all = None
        if new:  # after the subscription: a client that has the replay has the bus
            self.bridge.replay(new)

    def run(self, stop: Callable[[], bool], poll_s: float = 0.2) -> None:
        """Serve until ``stop()`` is true (checked at least every ``poll_s`` seconds)."""
        fd = self.lc.fileno()
        next_stats = time.monotonic() + 1.0
        while not stop():
            self._sync()
            ready, _, _ = select.select([fd, self._wake_r], [], [], poll_s)
            if self._wake_r in ready:
                os.read(self._wake_r, 4096)
            if fd in ready:
                self._receive(fd)
            now = time.monotonic()
            if now >= next_stats:
                next_stats = now + 1.0
                with self.listener.lock:
                    subs = len(self.listener.subs)
                self.bridge.log_stats({"auth_failed": self.counters["auth_failed"], "subscriptions": subs},
                                      time.time_ns())
        self._drain(fd)

    def _drain(self, fd: int, most_s: float = 2.0) -> None:
        """At the stop: what the bus had already sent, to the clients (up to ``most_s``; the SDK
        sends what it queued before it closes)."""
        end = time.monotonic() + most_s
        while time.monotonic() < end and select.select([fd], [], [], 0)[0]:
            self._receive(fd)

    def close(self) -> None:
        """Stop the server (its clients are disconnected)."""
        if self.server is not None:
            self.server.stop()
            self.server = None
        if self._closed:
            return
        self._closed = True
        for fd in (self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass
