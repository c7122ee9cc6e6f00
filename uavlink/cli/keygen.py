"""``uavlink keygen``: a MAVLink 2 signing key for ``uavlink fly`` and the vehicle."""

from __future__ import annotations

import argparse
from pathlib import Path

from uavlink.cli.options import output_file
from uavlink.errors import UserError


def cmd_keygen(args: argparse.Namespace) -> int:
    """Write a new MAVLink 2 signing key: 32 random bytes (os.urandom), mode 0600, never overwriting."""
    import hashlib

    from uavlink.mavlink.signing import write_key

    output_file(args.out, "--out")
    try:
        path = write_key(args.out)
    except FileExistsError:
        raise UserError(
            f"{args.out} exists; refusing to overwrite a key (delete it first)"
        ) from None
    except FileNotFoundError:  # as ssh-keygen: a key's folder is made on purpose, with its own mode
        raise UserError(
            f"cannot write {args.out}: its folder {args.out.parent} does not exist (create it "
            "first)"
        ) from None
    except OSError as exc:
        raise UserError(f"cannot write {args.out}: {exc.strerror or exc}") from None
    print(
        f"wrote a 32-byte MAVLink signing key to {path} (mode 0600, fingerprint "
        f"{hashlib.sha256(path.read_bytes()).hexdigest()[:8]}); give it to the vehicle and to "
        f"`uavlink fly` with --signing-key {path}"
    )
    return 0


def add_keygen_parser(sub) -> None:
    p = sub.add_parser(
        "keygen",
        help="make a MAVLink 2 signing key for fly and the vehicle",
        description="Write 32 random bytes (os.urandom) to a new file with mode 0600, "
        "for --signing-key of `uavlink fly` and `sitl-stub`. Never overwrites.",
    )
    p.add_argument("--out", type=Path, required=True, help="key file to create")
    p.set_defaults(func=cmd_keygen)
