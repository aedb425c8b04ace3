"""LCM messages to Foxglove channels, as the MCAP export writes them.

Each LCM channel of ours is one JSON channel named as the LCM channel, with
the schema generated from the ``.lcm`` files; the derived channels (``/tf``
frames B and D, ``/derived[/prefix]/pointing`` with the bound,
``/derived[/prefix]/wheels``) come from the same ``Deriver``; what is not
one well-formed message of its channel's type goes raw to
``<channel>/undecodable``, a channel of no type of ours raw under its own
name. All of it through ``sc_rt.export.channels`` and
``sc_rt.export.mcap_derived``: the code of the export, not a copy.

Work is done only for what a client listens to: a message whose channel and
derived channels have no subscriber is counted and dropped undecoded
(``idle``); one beyond its channel's rate (``ratelimit``) likewise. But
while a bench's ``/derived/pointing`` is listened to, every one of its
plant states gives its true attitude to the pointing (decoded for that
alone when it is not sent: the true error of each status sent, whichever
states the cap keeps). The
configuration and the controller's identity, sent once at a run's start,
are kept and sent again to a client that subscribes later (``LATCHED``).
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import foxglove
import sc_rt_lcm

from sc_rt.export.channels import (RAW_SCHEMA, JsonRows, channel_metadata, channel_schema, named_type, raw_row,
                                   typed_by_content)
from sc_rt.export.mcap_derived import Deriver, derive_order, derived_topics, pointing_topic
from sc_rt.live.ratelimit import DEFAULT_RATE_HZ, PERIODIC, MessageClock, RateLimiter
from sc_rt.live.ros2 import Ros2Type, twin_topic
from sc_rt.wire.codec import TYPES, decode_array
from sc_rt.wire.lcmdefs import load_definitions
from sc_rt.wire.lcmio import CHANNELS
from sc_rt.wire.lcmjson import dumps
from sc_rt.wire.startrec import decode_start

__all__ = ["Bridge", "STATS_TOPIC", "LATCHED"]

#: types sent once (a run's configuration, a controller's identity): their last
#: message is sent again to a client that subscribes later
LATCHED = frozenset({"controller_config_t", "controller_info_t"})

#: the bridge's own counters, once a second while a client listens
STATS_TOPIC = "/live/stats"
STATS_SCHEMA = {
    "title": "sc_rt.live_stats", "type": "object",
    "description": "sc-rt live's counters since it started (messages)",
    "properties": {k: {"type": "integer", "minimum": 0} for k in
                   ("received", "sent", "derived", "ratelimit", "idle", "undecodable", "auth_failed",
                    "subscriptions")},
}


class _Input:
    """One LCM channel as the bridge sees it."""

    __slots__ = ("name", "cls", "prefix", "rows", "clock", "limiter", "json", "raw", "derived")

    def __init__(self, name: str, cls, prefix: str | None):
        self.name, self.cls, self.prefix = name, cls, prefix
        self.rows = JsonRows(cls) if cls is not None else None
        self.clock = MessageClock(cls) if cls is not None else None
        self.limiter: RateLimiter | None = None
        self.json: Any = None  # foxglove.Channel of the decoded messages
        self.raw: Any = None  # foxglove.Channel of the raw events (created on the first)
        self.derived: list = []  # foxglove.Channel of each derived topic this type feeds


class Bridge:
    """The Foxglove channels of the LCM channels of a bus.

    Parameters
    ----------
    context : foxglove.Context
        The context of the server the channels are served by.
    prefix : str
        The bench's channel prefix: its channels are advertised before their
        first message (so that a client can subscribe before a run starts).
    max_rate : float
        [Hz] the cap of every periodic channel (``ratelimit.PERIODIC``); 0: none.
    rates : dict, optional
        {LCM channel or its name without prefix: Hz} overriding ``max_rate``.
    ros2 : bool
        Also each JSON channel's ROS 2 twin (``/ros2/<topic>``, cdr + ros2msg: ros2.py).
    """

    def __init__(self, context: Any, prefix: str = "", max_rate: float = DEFAULT_RATE_HZ,
                 rates: dict[str, float] | None = None, ros2: bool = False):
        self.ctx = context
        self.ros2 = ros2
        #: JSON channel id -> (its ROS 2 twin channel, the encoder)
        self.twins: dict[int, tuple[Any, Ros2Type]] = {}
        self.prefix = prefix
        self.max_rate, self.rates = max_rate, dict(rates or {})
        self.defs = load_definitions()
        self.deriver = Deriver()
        self.topics: dict[str, Any] = {}
        self.inputs: dict[str, _Input] = {}
        self.stats: Counter = Counter()
        self.kinds: Counter = Counter()
        self.non_finite = [0]
        #: the last message of each latched channel: (bytes, log time [ns])
        self.latest: dict[str, tuple[bytes, int]] = {}
        for base in CHANNELS:
            if CHANNELS[base][0] in TYPES:
                self._input(prefix + base, b"")
        self.topic(STATS_TOPIC, STATS_SCHEMA, {"derived": "sc-rt live"})

    # --- channels ------------------------------------------------------------
    def topic(self, topic: str, schema: dict, metadata: dict[str, str], name: str | None = None) -> Any:
        """The channel of ``topic`` (created, so advertised, on first use)."""
        ch = self.topics.get(topic)
        if ch is None:
            sch = foxglove.Schema(name=name or schema["title"], encoding="jsonschema", data=dumps(schema))
            ch = self.topics[topic] = foxglove.Channel(topic, schema=sch, message_encoding="json",
                                                       context=self.ctx, metadata=metadata)
            if self.ros2 and topic != STATS_TOPIC:
                r2 = Ros2Type(schema)
                twin = foxglove.Channel(twin_topic(topic), message_encoding="cdr", context=self.ctx,
                                        metadata=metadata, schema=foxglove.Schema(
                                            name=r2.name, encoding="ros2msg", data=r2.definition.encode()))
                self.twins[ch.id()] = (twin, r2)
        return ch

    def listened(self, ch: Any) -> bool:
        """Whether a client subscribes to ``ch`` or to its ROS 2 twin."""
        if ch.has_sinks():
            return True
        twin = self.twins.get(ch.id())
        return twin is not None and twin[0].has_sinks()

    def _log(self, ch: Any, row: bytes, log_ns: int) -> int:
        """``row`` to ``ch`` and to its twin, each when listened to; the messages sent."""
        n = 0
        if ch.has_sinks():
            ch.log(row, log_time=log_ns)
            n += 1
        twin = self.twins.get(ch.id())
        if twin is not None and twin[0].has_sinks():
            twin[0].log(twin[1].encode(row), log_time=log_ns)
            n += 1
        return n

    def _input(self, name: str, data: bytes) -> _Input:
        cls, prefix = named_type(name)
        if cls is None and data:
            cls = typed_by_content(data)  # an unnamed channel: typed by its first message of ours
        inp = self.inputs[name] = _Input(name, cls, prefix)
        if cls is None:
            return inp
        # the wheel command's unit: the bench's config seen so far (its config comes before its commands)
        schema_name, schema = channel_schema(cls, self.defs, self.deriver.torque.get(prefix, False))
        inp.json = self.topic(name, schema, channel_metadata(name, schema_name), schema_name)
        if prefix is not None:
            inp.derived = [self.topic(t, s, {"derived": "sc-rt live"}) for t, s in derived_topics(cls.__name__, prefix)]
            base = name[len(prefix):]
            rate = self.rates.get(name, self.rates.get(base, self.max_rate if base in PERIODIC else 0.0))
            if rate > 0:
                inp.limiter = RateLimiter(rate)
        return inp

    def _raw(self, inp: _Input, data: bytes, reason: str, log_ns: int) -> None:
        if inp.raw is None:
            topic = inp.name if inp.cls is None else inp.name + "/undecodable"
            inp.raw = self.topic(topic, RAW_SCHEMA, {"lcm_channel": inp.name, "content": "raw LCM events"})
        if self.listened(inp.raw):
            self.stats["sent"] += self._log(inp.raw, raw_row(inp.name, data, reason), log_ns)

    # --- one message -------------------------------------------------------------
    def wanted(self, inp: _Input) -> bool:
        """Whether a client listens to anything ``inp``'s messages feed."""
        return ((inp.json is not None and self.listened(inp.json)) or any(self.listened(c) for c in inp.derived)
                or (inp.raw is not None and self.listened(inp.raw)) or (inp.cls is None and inp.raw is None))

    def handle(self, events: list[tuple[str, bytes, int]]) -> None:
        """LCM messages (channel, bytes, receive time [ns, wall clock]) in
        arrival order: each channel's kept messages decoded at once (the
        configurations first, then guidance: frame D; as the export does)."""
        kept: dict[str, list[tuple[bytes, int]]] = {}
        truth: dict[str, list[bytes]] = {}  # prefix -> its states not sent, for the pointing's truth
        for name, data, log_ns in events:
            self.stats["received"] += 1
            inp = self.inputs.get(name)
            if inp is None or (inp.cls is None and inp.raw is None and data):
                inp = self._input(name, data)
            cls = inp.cls
            if name.endswith("SCRT_HIL_START") and (start := decode_start(data)) is not None:
                self.deriver.start(name[:-len("SCRT_HIL_START")], start)  # the law's telemetry names
            if cls is not None and cls.__name__ in LATCHED:
                self.latest[name] = (bytes(data), log_ns)
                if cls.__name__ == "controller_config_t" and inp.prefix is not None:
                    self.deriver.config(inp.prefix, data, latest=True)  # the pointing's bound, whoever listens
            if not self.wanted(inp):
                self.stats["idle"] += 1
            elif inp.limiter is not None and not inp.limiter.keep(inp.clock(data)):
                self.stats["ratelimit"] += 1
            else:
                kept.setdefault(name, []).append((data, log_ns))
                continue
            if cls is not None and cls.__name__ == "plant_state_t" and self._pointing_listened(inp.prefix):
                truth.setdefault(inp.prefix, []).append(data)
        for prefix, datas in truth.items():  # states not sent: their truth only (a kept one gives it in _emit)
            self.deriver.states(prefix, decode_array(sc_rt_lcm.plant_state_t, datas)[0])
        for name in sorted(kept, key=derive_order):  # configurations, guidance, states (the truth), the rest
            self._emit(self.inputs[name], kept[name])

    def _pointing_listened(self, prefix: str | None) -> bool:
        """Whether a client listens to the pointing of the bench of ``prefix``."""
        if prefix is None:
            return False
        ch = self.topics.get(pointing_topic(prefix))
        return ch is not None and self.listened(ch)

    def replay(self, channel_ids: set[int]) -> None:
        """The last message of each latched channel among ``channel_ids``, again (a client just subscribed)."""
        for name, (data, log_ns) in list(self.latest.items()):
            inp = self.inputs[name]
            if inp.json is not None and inp.json.id() in channel_ids:
                self._emit(inp, [(data, log_ns)])

    def _emit(self, inp: _Input, batch: list[tuple[bytes, int]]) -> None:
        cls = inp.cls
        if cls is None:
            for data, log_ns in batch:
                self._raw(inp, data, "foreign_channel", log_ns)
            return
        d = inp.rows.decode([data for data, _ in batch], self.kinds, self.non_finite)
        for j in sorted(d.bad):
            self.stats["undecodable"] += 1
            self._raw(inp, batch[j][0], d.bad[j], batch[j][1])
        times = [batch[j][1] for j in d.pos]
        if self.listened(inp.json):
            for row, log_ns in zip(d.rows, times):
                self.stats["sent"] += self._log(inp.json, row, log_ns)
        if d.rec is None or inp.prefix is None or not times:
            return
        for _counter, topic, schema, msgs in self.deriver.messages(cls.__name__, inp.prefix, d.rec,
                                                                   [t // 1000 for t in times]):
            ch = self.topic(topic, schema, {"derived": "sc-rt live"})
            if not self.listened(ch):
                continue
            for m, log_ns in zip(msgs, times):
                if m is not None:
                    self.stats["derived"] += self._log(ch, m, log_ns)

    def log_stats(self, extra: dict[str, int], log_ns: int) -> None:
        """The counters on STATS_TOPIC (when a client listens)."""
        ch = self.topics[STATS_TOPIC]
        if ch.has_sinks():
            row = {k: int(self.stats.get(k, 0)) for k in STATS_SCHEMA["properties"]}
            row.update({k: int(v) for k, v in extra.items()})
            ch.log(dumps(row), log_time=log_ns)
