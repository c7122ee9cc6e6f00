"""The uavlink command line: train | evaluate | fly | plot | export | sweep | keygen | policies.

A module per command (``evaluate``, ``train``, ``export``, ``sweep``, ``keygen``, ``fly``, ``plot``,
``policies``: each declares its options and imports what runs it, such as ``uavlink.flight.fly``,
when it runs) and the options they share (``options``).

User errors (bad arguments, unknown scenarios, unusable policy files, a missing optional package)
print one line on stderr and exit with status 2, without a traceback. Heavy modules are imported
only by the command that needs them.

May import: all of uavlink (the top layer).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from uavlink.errors import LinkError, OneLineParser, UserError, missing_extra


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="uavlink", description=__doc__.splitlines()[0])
    from uavlink import __version__

    parser.add_argument("--version", action="version", version=f"uavlink {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    from uavlink.cli.evaluate import add_evaluate_parser
    from uavlink.cli.export import add_export_parser
    from uavlink.cli.fly import add_fly_parser
    from uavlink.cli.keygen import add_keygen_parser
    from uavlink.cli.plot import add_plot_parser
    from uavlink.cli.policies import add_policies_parser
    from uavlink.cli.sweep import add_sweep_parser
    from uavlink.cli.train import add_train_parser

    for add in (
        add_evaluate_parser,
        add_train_parser,
        add_export_parser,
        add_sweep_parser,
        add_keygen_parser,
        add_fly_parser,
        add_plot_parser,
        add_policies_parser,
    ):
        add(sub)
    parser.set_defaults(commands=sub.choices)  # each command's parser, for its own errors
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:  # said by the command's parser (`uavlink fly: error: ...`), as its other errors are
        args.commands[args.command].error(f"unrecognized arguments: {' '.join(extra)}")
    try:
        return args.func(args)
    except UserError as exc:
        print(f"uavlink {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as exc:  # an optional package this command needs is not installed
        if (hint := missing_extra(exc)) is None:
            raise
        print(f"uavlink {args.command}: error: {hint}", file=sys.stderr)
        return 2
    except LinkError as exc:  # the vehicle was lost or refused: not the user's input, so status 1
        print(f"uavlink {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except BrokenPipeError:  # e.g. piped into head
        return 0
    except KeyboardInterrupt as exc:  # its message, if any, says what was kept
        print(
            f"uavlink {args.command}: interrupted" + (f"; {exc}" if str(exc) else ""),
            file=sys.stderr,
        )
        return 130
