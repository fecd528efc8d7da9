"""Command-line parsing of ``python -m sim_bridge``, kept apart from what it runs.

Turns ``argv`` into a :class:`BridgeOptions` or :class:`PlotOptions`; nothing here opens
anything. The Zenoh options follow zenoh-python's own examples (``--mode``,
``--connect``, ``--listen``, ``--zenoh-config``, ``--no-multicast-scouting``).
"""

import argparse
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from dbc import installed_version
from sim_bridge.cycle import MAX_STEPS
from sim_bridge.faults import FaultConfig, FaultWindow

#: The example machine configuration, shipped inside the ``dbc`` package next to its DBC
#: (``deploy/machine.example.toml`` in the repository points to it), so the simulator
#: runs from any directory and from an installed wheel. An on-disk install, as pip makes.
DEFAULT_CONFIG = Path(str(resources.files("dbc").joinpath("machine.example.toml")))

EPILOG = """\
fault windows are in seconds of simulated time since the bridge started:
  TARGET@START:DURATION  e.g. --silent SB2_F3@12:1 (TARGET: a leg, or a message for
                         --freeze-counter/--silent); --pause START:DURATION, e.g. 30:1
draw the cycle instead: portal-sim plot --out cycle.png (see plot --help);
portal-sim is python -m sim_bridge
"""


@dataclass(frozen=True)
class SourceOptions:
    """Where the cycle comes from: the model, or an external export with its mapping."""

    config_path: Path = DEFAULT_CONFIG
    rtol: float = 1e-5
    #: Add the model's seeded impulsive noise (co-simulation artefacts) to the pressures.
    noise: bool = False
    input_path: Path | None = None
    mapping_path: Path | None = None
    #: Seed of the noise and of the random faults; None: the noise's default, a fresh one
    #: for the faults.
    seed: int | None = None
    #: Steps the model plays as one cycle: 1 (SB2 lifted) or 2 (then SB1 lifted: a full
    #: walking cycle, each base lifted once).
    steps: int = 1


@dataclass(frozen=True)
class ZenohOptions:
    mode: str | None = None
    connect: tuple[str, ...] = ()
    listen: tuple[str, ...] = ()
    config_path: Path | None = None
    no_multicast_scouting: bool = False
    #: Key prefix; None means ``portal/<machine id>``.
    prefix: str | None = None


@dataclass(frozen=True)
class BridgeOptions:
    """Everything ``python -m sim_bridge`` (sending) is told."""

    source: SourceOptions = field(default_factory=SourceOptions)
    interface: str = "socketcan"
    channel: str = "vcan0"
    speed: float = 1.0
    #: Cycles to play; 0 loops until stopped.
    cycles: int = 1
    #: Stop after this much simulated time, s (None: after ``cycles``).
    duration_s: float | None = None
    as_fast_as_possible: bool = False
    faults: FaultConfig = field(default_factory=FaultConfig)
    truth_csv: Path | None = None
    truth_mcap: Path | None = None
    #: Write every n-th simulation sample as truth.
    truth_every: int = 1
    #: Also write every frame sent to this python-can log (.log, .blf, .asc); None: no.
    frames_log: Path | None = None
    #: Publish truth on Zenoh with these options; None: do not.
    zenoh: ZenohOptions | None = None


@dataclass(frozen=True)
class PlotOptions:
    source: SourceOptions
    out_path: Path


def _positive(kind: Callable[[str], float]) -> Callable[[str], float]:
    def parse(text: str) -> float:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if not (math.isfinite(value) and value > 0):
            raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
        return value

    return parse


def _non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return value


def _probability(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"must be a probability 0..1, got {text!r}")
    return value


#: Finest ``--rtol``: the solver's time grows ~3x per two decades (a 0.5 s run took 15 s
#: at 1e-7, 42 s at 1e-9); at 1e-300, which scipy takes as 2.2e-14, it had not ended
#: after 5 minutes.
MIN_RTOL = 1e-10


def _rtol(text: str) -> float:
    value = _positive(float)(text)
    if not MIN_RTOL <= value < 1:
        raise argparse.ArgumentTypeError(f"must be within [{MIN_RTOL:g}, 1), got {text!r}")
    return value


def _steps(text: str) -> int:
    value = _non_negative_int(text)
    if not 1 <= value <= MAX_STEPS:
        raise argparse.ArgumentTypeError(f"must be 1..{MAX_STEPS}, got {text!r}")
    return value


def _window(targeted: bool) -> Callable[[str], FaultWindow]:
    def parse(text: str) -> FaultWindow:
        try:
            return FaultWindow.parse(text, targeted=targeted)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    return parse


def _add_source_arguments(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("cycle source")
    group.add_argument(
        "--config",
        type=Path,
        default=DEFAULT_CONFIG,
        help="machine configuration (legs, DBC signals, foot areas) "
        "[the packaged example, dbc/machine.example.toml]",
    )
    group.add_argument(
        "--rtol", type=_rtol, default=1e-5, help="model solver's relative tolerance [%(default)g]"
    )
    group.add_argument(
        "--noise", action="store_true", help="add the model's seeded impulsive pressure noise"
    )
    group.add_argument(
        "--seed", type=_non_negative_int, help="seed of --noise, --drop and --bad-crc"
    )
    group.add_argument(
        "--steps", type=_steps, default=1,
        help="model steps per cycle: 1 (SB2 lifted) or 2 (then SB1: a full walking cycle) [1]",
    )  # fmt: skip
    group.add_argument("--input", type=Path, help="external export (.csv or .mat) instead")
    group.add_argument("--mapping", type=Path, help="TOML mapping of --input's columns")


def _source(parser: argparse.ArgumentParser, args: argparse.Namespace) -> SourceOptions:
    if (args.input is None) != (args.mapping is None):
        parser.error("--input and --mapping go together")
    if args.input is not None and args.steps != 1:
        parser.error("--steps is the model's: an --input export is played as it is")
    return SourceOptions(
        args.config, args.rtol, args.noise, args.input, args.mapping, args.seed, args.steps
    )


def run_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="portal-sim",
        description="Play the simulated movement cycle onto a CAN bus, with ground truth.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_source_arguments(parser)
    bus = parser.add_argument_group("bus and timing")
    bus.add_argument("--interface", default="socketcan", help="python-can interface [%(default)s]")
    bus.add_argument("--channel", default="vcan0", help="python-can channel [%(default)s]")
    bus.add_argument("--speed", type=_positive(float), default=1.0, help="x real time [1]")
    bus.add_argument("--cycles", type=_non_negative_int, default=1, help="cycles, 0 = loop [1]")
    bus.add_argument(
        "--duration", type=_positive(float), help="stop after this much simulated time, s"
    )
    bus.add_argument(
        "--as-fast-as-possible",
        action="store_true",
        help="never sleep; frames and truth are stamped at their due times, so with "
        "--interface virtual --frames-log the log of a cycle needs no bus",
    )
    faults = parser.add_argument_group("faults (see the epilog for windows)")
    faults.add_argument("--drop", type=_probability, default=0.0, help="frame loss probability")
    faults.add_argument("--bad-crc", type=_probability, default=0.0, help="bad CRC probability")
    for flag, what in (
        ("--freeze-counter", "rolling counter stops"),
        ("--silent", "message not sent"),
        ("--stuck", "leg pressures frozen"),
        ("--out-of-range", "leg piston pressure 45 MPa"),
        ("--sensor-fault", "leg status sensor_fault"),
    ):
        faults.add_argument(
            flag, type=_window(True), action="append", default=[], metavar="T@S:D", help=what
        )
    faults.add_argument(
        "--pause", type=_window(False), action="append", default=[], metavar="S:D",
        help="nothing sent",
    )  # fmt: skip
    parser.add_argument(
        "--frames-log",
        type=Path,
        metavar="FILE",
        help="also write every frame sent to this python-can log: .log (candump), .blf or "
        ".asc, for `portal-daq replay FILE --config ...`",
    )
    truth = parser.add_argument_group("ground truth")
    truth.add_argument("--truth-csv", type=Path, metavar="PATH", help="write truth as CSV")
    truth.add_argument("--truth-mcap", type=Path, metavar="PATH", help="write truth as MCAP")
    truth.add_argument(
        "--truth-every", type=_positive(int), default=1, metavar="N",
        help="write every N-th simulation sample (10 ms) [1]",
    )  # fmt: skip
    zenoh = parser.add_argument_group("Zenoh (truth on <prefix>/sim/truth[/<LEG>])")
    zenoh.add_argument("--zenoh", action="store_true", help="publish truth on Zenoh")
    zenoh.add_argument("--zenoh-config", type=Path, metavar="FILE", help="Zenoh config file")
    zenoh.add_argument("--mode", choices=("peer", "client"), help="Zenoh session mode")
    zenoh.add_argument("--connect", action="append", default=[], metavar="ENDPOINT")
    zenoh.add_argument("--listen", action="append", default=[], metavar="ENDPOINT")
    zenoh.add_argument("--no-multicast-scouting", action="store_true")
    zenoh.add_argument("--zenoh-prefix", metavar="KEY", help="key prefix [portal/<machine id>]")
    _add_logging_arguments(parser)
    parser.add_argument("--version", action="version", version=f"portal-sim {installed_version()}")
    return parser


def plot_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="portal-sim plot",
        description="Draw the cycle's contact pressure (kPa) and force (kN) per foot to a PNG.",
    )
    parser.add_argument("--out", type=Path, required=True, metavar="FILE.png")
    _add_source_arguments(parser)
    _add_logging_arguments(parser)
    return parser


def _add_logging_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug lines too")
    parser.add_argument("-q", "--quiet", action="store_true", help="log warnings and errors only")


def parse_args(argv: Sequence[str]) -> tuple[BridgeOptions | PlotOptions, argparse.Namespace]:
    """Options for ``argv`` (without the program name); argparse exits 2 on bad usage."""
    if argv and argv[0] == "plot":
        parser = plot_parser()
        args = parser.parse_args(argv[1:])
        return PlotOptions(_source(parser, args), args.out), args
    parser = run_parser()
    args = parser.parse_args(argv)
    zenoh_asked = (
        args.zenoh_config
        or args.mode
        or args.connect
        or args.listen
        or args.zenoh_prefix
        or args.no_multicast_scouting
    )
    if zenoh_asked and not args.zenoh:
        parser.error("Zenoh options need --zenoh")
    faults = FaultConfig(
        drop_probability=args.drop,
        bad_crc_probability=args.bad_crc,
        freeze_counter=tuple(args.freeze_counter),
        silent=tuple(args.silent),
        stuck=tuple(args.stuck),
        out_of_range=tuple(args.out_of_range),
        sensor_fault=tuple(args.sensor_fault),
        pause=tuple(args.pause),
        seed=args.seed,
    )
    zenoh = (
        ZenohOptions(
            mode=args.mode,
            connect=tuple(args.connect),
            listen=tuple(args.listen),
            config_path=args.zenoh_config,
            no_multicast_scouting=args.no_multicast_scouting,
            prefix=args.zenoh_prefix,
        )
        if args.zenoh
        else None
    )
    options = BridgeOptions(
        source=_source(parser, args),
        interface=args.interface,
        channel=args.channel,
        speed=args.speed,
        cycles=args.cycles,
        duration_s=args.duration,
        as_fast_as_possible=args.as_fast_as_possible,
        faults=faults,
        truth_csv=args.truth_csv,
        truth_mcap=args.truth_mcap,
        truth_every=args.truth_every,
        frames_log=args.frames_log,
        zenoh=zenoh,
    )
    return options, args
