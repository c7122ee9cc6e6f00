"""Pictures of a flight (``uavlink plot``, and the ``flight.png`` that ``uavlink fly`` writes):
``tlog`` (read the messages a picture needs from a tlog, checked by CRC), ``picture`` (the map, the
throughput and the SINRs), ``animation`` (``--gif``, a frame per decision) and ``command`` (the CLI
and the picture after a flight). matplotlib is imported only when drawing (the ``plot`` extra).

May import: ``errors`` and ``mavlink`` (the dialect, geo, modes, radio codec, UE truth); never the
flight loop, so a picture is drawn from a tlog alone.
"""
