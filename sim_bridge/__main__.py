"""``python -m sim_bridge``: play the simulated movement cycle onto a CAN bus, with truth.

``python -m sim_bridge [options]`` sends; ``python -m sim_bridge plot --out FILE.png``
draws the cycle (``--help`` on each). Argument parsing lives in :mod:`sim_bridge._args`;
:func:`main` and :func:`plot_main` take the parsed options. Every resource (the CAN bus,
the truth files, the Zenoh session) is opened here and handed to the pieces that use
it. SIGINT and SIGTERM stop the run after the current instant and close everything
(the MCAP file gets its footer). An error the project raises on purpose
(:class:`~dbc.errors.PortalDaqError`) ends the program with one line on stderr and
exit status 2; so does bad usage (argparse).
"""

import logging
import signal
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import replace
from pathlib import Path
from types import FrameType
from typing import IO, Any

import can
from can.io.generic import MessageWriter

from dbc.bus_hints import bus_hint
from dbc.decoding import is_fd_message
from dbc.encoding import FrameEncoder
from dbc.errors import ConfigError, PortalDaqError
from dbc.machine import MachineConfig, load_machine_config
from estimator.geometry import LegGeometry
from sim_bridge._args import BridgeOptions, PlotOptions, SourceOptions, ZenohOptions, parse_args
from sim_bridge.emitter import Emitter, EmitterStats, end_of_run_ns
from sim_bridge.faults import FaultConfig, FaultInjector
from sim_bridge.frames import FrameBuilder
from sim_bridge.leg_map import leg_map
from sim_bridge.playout import Playout, fault_targets
from sim_bridge.result import LEGS, SimulationResult
from sim_bridge.truth import CsvTruthWriter, McapTruthWriter, TruthSink, ZenohTruthPublisher

logger = logging.getLogger("sim_bridge")

#: python-can log formats ``--frames-log`` writes (by suffix) and ``portal-daq replay``
#: reads back: candump text, Vector BLF, Vector ASC.
FRAMES_LOG_SUFFIXES = (".log", ".blf", ".asc")


def load_source(source: SourceOptions, config: MachineConfig) -> SimulationResult:
    """The cycle to play: the external export when given, else the model's simulation."""
    legs = leg_map(config)  # first: legs the bridge cannot play stop before the model runs
    if source.input_path is not None and source.mapping_path is not None:
        from sim_bridge.external import load_external

        result = load_external(source.input_path, source.mapping_path, legs.simulated)
        logger.info(
            "cycle: %s via %s, %d samples of %g s",
            source.input_path,
            source.mapping_path,
            len(result),
            result.dt_s,
        )
        return result
    # Imported here: the model (scipy's solver) is needed only when it runs.
    from sim_bridge.model import simulate
    from sim_bridge.noise import ImpulsiveNoise
    from sim_bridge.params import ModelParams

    leg = next(iter(config.legs.values())).geometry
    params = ModelParams(leg=leg, legs=column_geometries(config, legs.columns, leg))
    if abs(params.mass_kg - config.mass_kg) > 0.01 * config.mass_kg:
        logger.warning(
            "the model's mass (%.0f kg) differs from the config's (%.0f kg)",
            params.mass_kg,
            config.mass_kg,
        )
    noise = None
    if source.noise:
        noise = ImpulsiveNoise() if source.seed is None else ImpulsiveNoise(seed=source.seed)
    started_s = time.monotonic()
    try:
        result = simulate(params, rtol=source.rtol, noise=noise, steps=source.steps)
    except RuntimeError as exc:  # the solver gave up
        raise ConfigError("--rtol", "", f"{exc}; try a smaller --rtol") from exc
    logger.info(
        "cycle: model, %d step(s) at rtol %g%s, %d samples of %g s, simulated in %.1f s",
        source.steps,
        source.rtol,
        " with impulsive noise" if noise else "",
        len(result),
        result.dt_s,
        time.monotonic() - started_s,
    )
    return result


def column_geometries(
    config: MachineConfig, columns: Mapping[str, int], default: LegGeometry
) -> tuple[LegGeometry, ...]:
    """Each simulated leg's geometry (by column): that of the config leg played on it
    (``default`` where none is). Legs of other geometries on one column (more legs than
    the simulation's) cannot all be met: the first's, with a warning naming them."""
    played: dict[int, list[str]] = {}
    for name, column in columns.items():
        played.setdefault(column, []).append(name)
    geometries = []
    for column, simulated in enumerate(LEGS):
        names = played.get(column, [])
        geometry = config.legs[names[0]].geometry if names else default
        # The calibration (force_gain, force_offset_N) is the estimator's, not the design's.
        others = [
            name
            for name in names[1:]
            if replace(config.legs[name].geometry, force_gain=1.0, force_offset_N=0.0)
            != replace(geometry, force_gain=1.0, force_offset_N=0.0)
        ]
        for other in others:
            logger.warning(
                "legs.%s is played as %s with legs.%s, of another geometry: it is sent "
                "that leg's pressures, so eq. (4) reads other forces than its truth",
                other,
                simulated,
                names[0],
            )
        geometries.append(geometry)
    return tuple(geometries)


def _open_bus(interface: str, channel: str, fd: bool) -> can.BusABC:
    """The bus to send on; ``fd``: some messages are CAN FD (SocketCAN needs it said)."""
    try:
        return can.Bus(interface=interface, channel=channel, fd=fd)
    except (can.CanError, OSError, ValueError, ImportError) as exc:
        hint = bus_hint(exc, channel, channel_option="--channel", interface_option="--interface")
        if not hint and interface == "socketcan":
            hint = (
                f"is {channel} there and up? e.g. sudo ip link add dev {channel} type vcan "
                f"&& sudo ip link set {channel} up"
            )
        hint = f"; {hint}" if hint else ""
        reason = getattr(exc, "strerror", None) or exc
        option = f"--interface {interface} --channel {channel}"
        raise ConfigError(option, "", f"cannot open the bus: {reason}{hint}") from exc


def _open_output(path: Path, mode: str) -> IO[Any]:
    try:
        if "b" in mode:
            return open(path, mode)
        return open(path, mode, newline="", encoding="utf-8")
    except OSError as exc:
        raise ConfigError(path, "", f"cannot write it: {exc.strerror or exc}") from exc


def _open_frames_log(path: Path) -> MessageWriter:
    """A python-can writer for ``path``, chosen by its suffix (see FRAMES_LOG_SUFFIXES)."""
    if path.suffix.lower() not in FRAMES_LOG_SUFFIXES:
        raise ConfigError(
            path,
            "",
            f"--frames-log: no log format for {path.suffix or 'no suffix'!r}; "
            f"use {', '.join(FRAMES_LOG_SUFFIXES)}",
        )
    try:
        return can.Logger(path)
    except OSError as exc:
        raise ConfigError(path, "", f"cannot write it: {exc.strerror or exc}") from exc


def zenoh_config(options: ZenohOptions) -> Any:
    """A ``zenoh.Config`` from the options, as zenoh-python's examples build it; a file or
    value Zenoh refuses is one line naming the option that gave it."""
    import zenoh

    from dbc.zenoh_config import put, read_config_file  # Zenoh loads only with --zenoh

    if options.config_path is not None:
        config = read_config_file(options.config_path, "--zenoh-config")
    else:
        config = zenoh.Config()
    if options.mode is not None:
        put(config, "mode", options.mode, source="--mode")
    if options.connect:
        put(config, "connect/endpoints", list(options.connect), source="--connect")
    if options.listen:
        put(config, "listen/endpoints", list(options.listen), source="--listen")
    if options.no_multicast_scouting:
        put(config, "scouting/multicast/enabled", False, source="--no-multicast-scouting")
    return config


def _open_zenoh(options: ZenohOptions) -> Any:
    import zenoh

    from dbc.zenoh_config import one_line

    config = zenoh_config(options)
    try:
        return zenoh.open(config)
    except zenoh.ZError as exc:
        raise ConfigError(
            "--zenoh",
            "",
            f"cannot open a Zenoh session: {one_line(str(exc))}; check --connect, --listen "
            "and --mode: is the service or router there, is a --listen port taken?",
        ) from exc


@contextmanager
def _stop_on_signals(stop: Callable[[], None]) -> Iterator[list[int]]:
    """SIGINT/SIGTERM call ``stop``; yields the list of signals received."""
    received: list[int] = []

    def handler(signum: int, frame: FrameType | None) -> None:
        received.append(signum)  # no logging here: a handler must not take logging's lock
        stop()

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield received
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def describe_faults(faults: FaultConfig) -> str:
    parts = []
    if faults.drop_probability:
        parts.append(f"drop {faults.drop_probability:g}")
    if faults.bad_crc_probability:
        parts.append(f"bad-crc {faults.bad_crc_probability:g}")
    for name in ("freeze_counter", "silent", "stuck", "out_of_range", "sensor_fault", "pause"):
        for window in getattr(faults, name):
            parts.append(f"{name.replace('_', '-')} {window}")
    return ", ".join(parts)


def main(options: BridgeOptions) -> int:
    """Play the cycle per ``options``; returns the exit status (0)."""
    config, database = load_machine_config(options.source.config_path)
    result = load_source(options.source, config)
    builder = FrameBuilder(config, database)
    logger.info("legs played (config=simulated, by %s): %s", builder.leg_map.rule, builder.leg_map)
    if builder.skipped:
        logger.info(
            "not sent (the simulation has none of their signals, or nested multiplexing): %s",
            builder.skipped,
        )
    if builder.defaulted:
        logger.info("sent as constant 0 (no simulated value): %s", builder.defaulted)
    if absent := config.signals.absent():
        logger.info(
            "no signal in the DBC for [signals] %s, not sent (where the DBC names them "
            'otherwise: [signals] phase = "MESSAGE.SIGNAL", ...)',
            ", ".join(absent),
        )
    injector = FaultInjector(options.faults, fault_targets(builder))
    if options.faults.any:
        logger.info("faults: %s; seed %d", describe_faults(options.faults), injector.seed)
    playout = Playout(result, builder, FrameEncoder.from_config(config, database), injector)
    end_ns = end_of_run_ns(playout.timeline.cycle_ns, options.cycles, options.duration_s)
    legs = list(config.legs)
    feet_m2 = {leg: config.legs[leg].geometry.A_foot_m2 for leg in legs}
    with ExitStack() as stack:
        fd = any(
            is_fd_message(database.get_message_by_name(builder.target(s)[0]))
            for s in builder.messages
        )
        bus = stack.enter_context(_open_bus(options.interface, options.channel, fd))
        sinks: list[TruthSink] = []
        if options.truth_csv is not None:
            stream = stack.enter_context(_open_output(options.truth_csv, "w"))
            sinks.append(stack.enter_context(CsvTruthWriter(stream, legs)))
        if options.truth_mcap is not None:
            stream = stack.enter_context(_open_output(options.truth_mcap, "wb"))
            sinks.append(stack.enter_context(McapTruthWriter(stream, legs)))
        frames_log: can.Listener | None = None
        if options.frames_log is not None:
            frames_log = stack.enter_context(_open_frames_log(options.frames_log))
        if options.zenoh is not None:
            session = _open_zenoh(options.zenoh)
            stack.callback(session.close)
            prefix = options.zenoh.prefix or f"portal/{config.machine_id}"
            publisher = stack.enter_context(ZenohTruthPublisher(session, prefix, legs))
            sinks.append(publisher)
            logger.info("publishing truth on Zenoh under %s", publisher.key)
        emitter = Emitter(
            bus,
            playout,
            end_sim_ns=end_ns,
            speed=options.speed,
            as_fast_as_possible=options.as_fast_as_possible,
            truth_sinks=sinks,
            feet_m2=feet_m2,
            truth_every=options.truth_every,
            frames_log=frames_log,
        )
        logger.info(
            "playing %s of %.2f s on %s %s",
            f"{options.cycles} cycle(s)" if options.cycles else "cycles until stopped",
            playout.timeline.cycle_ns / 1e9,
            options.interface,
            options.channel,
        )
        started_s = time.monotonic()
        with _stop_on_signals(emitter.stop) as received:
            stats = emitter.run()
        if received:
            logger.info("stopped by %s", signal.Signals(received[0]).name)
        log_summary(stats, time.monotonic() - started_s)
    return 0


def log_summary(stats: EmitterStats, elapsed_s: float) -> None:
    total = sum(stats.sent.values())
    logger.info(
        "sent %d frames in %.2f s (%.0f frames/s), %.2f s simulated: %s",
        total,
        elapsed_s,
        total / elapsed_s if elapsed_s > 0 else 0.0,
        stats.sim_time_s,
        ", ".join(f"{name} {count}" for name, count in stats.sent.items()),
    )
    counts = stats.faults
    touched = {
        "dropped": counts.dropped,
        "bad CRC": counts.bad_crc,
        "frozen counter": counts.frozen_counter,
        "silent": counts.silent,
        "paused": counts.paused,
        "send errors": stats.send_errors,
    }
    totals = {what: sum(counter.values()) for what, counter in touched.items()}
    if any(totals.values()):
        logger.info(
            "frames %s", ", ".join(f"{what} {total}" for what, total in totals.items() if total)
        )
    if stats.late_instants:
        logger.warning(
            "%d instants went out late, the worst by %.1f ms",
            stats.late_instants,
            stats.max_lateness_s * 1e3,
        )
    if stats.truth_samples:
        logger.info("wrote %d truth samples", stats.truth_samples)


def plot_main(options: PlotOptions) -> int:
    """Draw the cycle to ``options.out_path``; returns the exit status (0)."""
    from sim_bridge.plot import write_cycle_plot  # matplotlib loads only to draw

    config, _ = load_machine_config(options.source.config_path)
    columns = leg_map(config).columns
    result = load_source(options.source, config)
    with _open_output(options.out_path, "wb") as stream:
        geometries = {leg: config.legs[leg].geometry for leg in config.legs}
        title = f"{config.machine_id}: one cycle"
        write_cycle_plot(result, geometries, stream, title, columns)
    logger.info("wrote %s", options.out_path)
    return 0


def cli(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` (default: ``sys.argv[1:]``), set up logging, run; the exit status."""
    options, args = parse_args(sys.argv[1:] if argv is None else argv)
    level = logging.DEBUG if args.verbose else logging.WARNING if args.quiet else logging.INFO
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    try:
        if isinstance(options, PlotOptions):
            return plot_main(options)
        return main(options)
    except PortalDaqError as exc:
        sys.stderr.write(f"sim_bridge: {' '.join(str(exc).split())}\n")
        return 2
    except KeyboardInterrupt:  # Ctrl-C before the run started (e.g. while simulating)
        logger.info("interrupted")
        return 130


if __name__ == "__main__":
    sys.exit(cli())
