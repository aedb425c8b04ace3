"""``sc-rt live``: a bus served to Foxglove and PlotJuggler as it runs
(sc_rt/live/); ``sc-rt hil --live [PORT]`` starts it beside a run."""

from __future__ import annotations

import argparse
import sys

from sc_rt.cli.validate import AUTH_KEY_HELP, auth_key_file, integer, lcm_url, number

__all__ = ["add_parser", "add_hil_option", "cmd_live", "rate_item"]

_PORT = integer(0, 65535)


def rate_item(text: str) -> str:
    """type=: ``CHANNEL=HZ`` (HZ >= 0)."""
    from sc_rt.live.ratelimit import parse_rates

    try:
        parse_rates([text])
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: must be CHANNEL=HZ with HZ >= 0 (0: every message)") from None
    return text


def add_parser(sub) -> None:
    """The ``sc-rt live`` subcommand."""
    from sc_rt.live.ratelimit import DEFAULT_RATE_HZ
    from sc_rt.live.server import DEFAULT_PORT

    v = sub.add_parser("live", help="serve the bus live on a Foxglove WebSocket (Foxglove, PlotJuggler)")
    v.add_argument("--lcm-url", metavar="URL", type=lcm_url,
                   help="default: $SCRT_LCM_URL, else udpm://239.255.76.67:7667?ttl=0 (sc-rt hil prints its URL)")
    v.add_argument("--prefix", default="", help="the bench's channel prefix (default: none)")
    v.add_argument("--auth-key", metavar="FILE", type=auth_key_file, help=AUTH_KEY_HELP)
    v.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default: %(default)s; 0.0.0.0: every interface)")
    v.add_argument("--port", type=_PORT, default=DEFAULT_PORT, metavar="N",
                   help="WebSocket port (default: %(default)s; 0: a free one, printed)")
    v.add_argument("--max-rate", type=number(0, 1e6, open_lo=False), default=DEFAULT_RATE_HZ, metavar="HZ",
                   help="cap of each periodic channel, in the messages' own time (default: %(default)s; "
                        "0: every message)")
    v.add_argument("--rate", action="append", type=rate_item, metavar="CHANNEL=HZ",
                   help="cap of one channel (repeatable; e.g. SCRT_CTRL_STATUS=200)")
    v.add_argument("--backlog", type=integer(1, 10_000_000), default=1024, metavar="N",
                   help="messages queued per client; a slower client loses the oldest (default: %(default)s)")
    v.add_argument("--ros2", action="store_true",
                   help="also each topic as ROS 2 (cdr + ros2msg) under /ros2/...: what PlotJuggler's Foxglove "
                        "Bridge client lists (docs/LOGS.md, 'Live')")
    v.add_argument("--layout", action="store_true", help="print the path of the shipped Foxglove layout and exit")
    v.set_defaults(func=cmd_live)


def add_hil_option(h) -> None:
    """``sc-rt hil --live [PORT]``."""
    from sc_rt.live.server import DEFAULT_PORT

    h.add_argument("--live", nargs="?", const=DEFAULT_PORT, type=_PORT, metavar="PORT",
                   help=f"serve the run live on ws://127.0.0.1:PORT (default PORT {DEFAULT_PORT}; sc-rt live)")


def cmd_live(args: argparse.Namespace) -> int:
    """Serve until SIGINT or SIGTERM (exit 0); 2 when it cannot start."""
    from sc_rt.cli.common import bus_url
    from sc_rt.cli.interrupts import flag_signals
    from sc_rt.live.layout import LAYOUT
    from sc_rt.live.ratelimit import parse_rates
    from sc_rt.live.server import LiveError, LiveServer
    from sc_rt.wire.auth import load_key

    if args.layout:
        print(LAYOUT)
        return 0
    url = bus_url(args)
    srv = LiveServer(url, prefix=args.prefix, host=args.host, port=args.port, max_rate=args.max_rate,
                     rates=parse_rates(args.rate), auth_key=load_key(args.auth_key), backlog=args.backlog,
                     ros2=args.ros2)
    try:
        srv.start()
    except LiveError as e:
        print(f"sc-rt live: error: {e}", file=sys.stderr)
        return 2
    try:
        with flag_signals(lambda _s: None) as signals:
            print(f"sc-rt live: serving {url}" + (f" (prefix {args.prefix!r})" if args.prefix else "")
                  + f" on {srv.ws_url} (subprotocol foxglove.sdk.v1); layout: {LAYOUT}", flush=True)
            srv.run(lambda: bool(signals))
    finally:
        srv.close()
    return 0
