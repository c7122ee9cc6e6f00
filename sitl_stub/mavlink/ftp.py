"""A MAVLink FTP responder that has no files: every open or listing is refused.

PX4 serves parameters and metadata over MAVLink FTP; this stub does not. MAVProxy tries FTP first
for its parameter download and falls back to PARAM_REQUEST_LIST on a refusal, so answering
promptly (instead of letting its requests time out) makes it fetch parameters at once.
"""

from __future__ import annotations

OP_TERMINATE_SESSION = 1
OP_RESET_SESSIONS = 8
OP_ACK = 128
OP_NAK = 129
ERR_FILE_NOT_FOUND = 10
PAYLOAD_LEN = 251


def ftp_reply(request: bytes | list[int]) -> list[int] | None:
    """The FILE_TRANSFER_PROTOCOL payload answering ``request``, or None for a reply/garbage."""
    req = bytes(request)
    if len(req) < 12 or req[3] in (OP_ACK, OP_NAK):
        return None
    out = bytearray(PAYLOAD_LEN)
    seq = int.from_bytes(req[0:2], "little")
    out[0:2] = ((seq + 1) & 0xFFFF).to_bytes(2, "little")
    out[2] = req[2]  # session
    out[5] = req[3]  # req_opcode
    if req[3] in (OP_TERMINATE_SESSION, OP_RESET_SESSIONS):
        out[3] = OP_ACK
    else:
        out[3] = OP_NAK
        out[4] = 1
        out[12] = ERR_FILE_NOT_FOUND
    return list(out)
