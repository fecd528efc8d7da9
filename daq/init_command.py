"""``portal-daq init [DIR] [--example NAME] [--deploy]``: write an example configuration to
start from, and with ``--deploy`` the kit that installs the service on the machine.

The examples ship inside the package (``daq/examples/<name>/``; ``deploy/`` links to
them), so whoever installed the wheel gets the same files as a clone of the repository:
the service + machine TOML, the Zenoh configuration it names and, for the machines
with a DBC of their own, that DBC. So does the deployment kit (``daq/deploy/``:
``install.sh``, the systemd unit and sysusers file, the sysctl and networkd drop-ins;
``deploy/`` of the repository links to them), written into ``DIR/deploy/``. Existing
files are never overwritten without ``--force``: nothing is written then, and the one
line on stderr names them.
"""

import argparse
import shlex
import sys
from collections.abc import Sequence
from importlib import resources
from importlib.resources.abc import Traversable
from pathlib import Path

from daq.subcommand import PROG, Subcommand, fail
from dbc.errors import ConfigError

#: The examples, one folder each.
EXAMPLES = resources.files("daq") / "examples"
#: The deployment kit: install.sh and the files it installs, in folders.
DEPLOY = resources.files("daq") / "deploy"
#: The kit's programs (written executable).
DEPLOY_SCRIPTS = ("install.sh",)
#: The file of every example that ``portal-daq run --config`` takes.
CONFIG_NAME = "portal-daq.toml"


def example_names() -> list[str]:
    """The shipped examples, sorted (``default`` is the prototype's own DBC)."""
    return sorted(entry.name for entry in EXAMPLES.iterdir() if entry.is_dir())


def example_files(name: str) -> list[Traversable]:
    """The files of example ``name``, sorted by name."""
    return sorted((entry for entry in (EXAMPLES / name).iterdir() if entry.is_file()),
                  key=lambda entry: entry.name)  # fmt: skip


def write_example(
    name: str, directory: Path, *, force: bool = False, deploy: bool = False
) -> list[Path]:
    """Copy example ``name`` into ``directory`` (created), with ``deploy`` the deployment
    kit into ``directory/deploy`` (``install.sh`` executable); the paths written.

    Raises ``FileExistsError`` naming the files that exist (none is written) unless
    ``force``, :class:`~dbc.errors.ConfigError` when ``directory`` is a file, and
    ``OSError`` when the directory cannot be written.
    """
    files = [(entry, directory / entry.name) for entry in example_files(name)]
    if deploy:
        files += [(entry, directory / "deploy" / path) for entry, path in deploy_files()]
    written = _write(files, force)
    if deploy:
        for script in DEPLOY_SCRIPTS:
            (directory / "deploy" / script).chmod(0o755)
    return written


def deploy_files(
    folder: Traversable = DEPLOY, under: Path = Path()
) -> list[tuple[Traversable, Path]]:
    """The deployment kit's files with their paths in it, sorted (``install.sh``,
    ``systemd/portal-daq.service``, ...)."""
    found: list[tuple[Traversable, Path]] = []
    for entry in sorted(folder.iterdir(), key=lambda entry: entry.name):
        if entry.is_dir():
            found += deploy_files(entry, under / entry.name)
        elif entry.is_file() and not entry.name.startswith("."):
            found.append((entry, under / entry.name))
    return found


def _write(files: list[tuple[Traversable, Path]], force: bool) -> list[Path]:
    """Write each (packaged file, target) pair; see :func:`write_example`."""
    for directory in {target.parent for _, target in files}:
        if directory.exists() and not directory.is_dir():
            raise ConfigError(directory, "", "it is a file; give init a directory to write into")
    existing = [str(target) for _, target in files if target.exists()]
    if existing and not force:
        exist, them = ("exists", "it") if len(existing) == 1 else ("exist", "them")
        raise FileExistsError(f"{', '.join(existing)} {exist}; --force overwrites {them}")
    for entry, target in files:
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(entry.read_bytes())
    return [target for _, target in files]


def init_main(args: Sequence[str]) -> int:
    names = example_names()
    parser = argparse.ArgumentParser(
        prog=f"{PROG} init",
        description="Write an example service + machine configuration (with the Zenoh "
        "configuration it names and its DBC) into a directory, to edit and then run with "
        f"`{PROG} run --config DIR/{CONFIG_NAME}`. Examples: default (this prototype's "
        "DBC), j1939 (one J1939 transducer per chamber), e2e (AUTOSAR E2E protected frames).",
    )
    parser.add_argument("directory", nargs="?", type=Path, default=Path("."),
                        help="where to write (created; default: here)")  # fmt: skip
    parser.add_argument("--example", choices=names, default="default", help="which machine")
    parser.add_argument("--force", action="store_true", help="overwrite existing files")
    parser.add_argument(
        "--deploy",
        action="store_true",
        help="also write DIR/deploy/: install.sh and the systemd unit, sysusers, sysctl and "
        "networkd files it installs (`sudo DIR/deploy/install.sh --package WHEEL` installs "
        "the service with this configuration)",
    )
    options = parser.parse_args(args)
    try:
        written = write_example(
            options.example, options.directory, force=options.force, deploy=options.deploy
        )
    except (FileExistsError, ConfigError) as exc:
        return fail(exc, 2)
    except OSError as exc:
        return fail(f"{options.directory}: cannot write the example: {exc.strerror or exc}", 1)
    # quoted as a shell needs them: the lines are commands to copy (`my machine/...`)
    config = shlex.quote(str(options.directory / CONFIG_NAME))
    sys.stderr.write(
        f"{PROG}: wrote {', '.join(str(path) for path in written)}\n"
        f"{PROG}: edit [bus] channel, [recording] directory and the machine tables, then "
        f"`{PROG} run --config {config}` (`{PROG} replay LOG --config {config}` for a CAN log)\n"
    )
    if options.deploy:
        install = shlex.quote(str(options.directory / "deploy" / "install.sh"))
        sys.stderr.write(
            f"{PROG}: on the machine, `sudo {install} --package WHEEL` installs the service "
            f"(/opt/portal-daq/venv, this configuration in /etc/portal-daq, the systemd unit); "
            f"`{install} --help` says what goes where\n"
        )
    return 0


SUBCOMMAND = Subcommand("init", "write an example configuration to start from", init_main)
