"""MAVLink pieces both ends of the flight link share: ``uavlink fly`` and the ``sitl_stub`` vehicle.

- :mod:`~uavlink.mavlink.dialect`: the one place that imports pymavlink (MAVLink 2, ``common``);
- :mod:`~uavlink.mavlink.connection`: connection strings;
- :mod:`~uavlink.mavlink.signing`: MAVLink 2 message signing and key files;
- :mod:`~uavlink.mavlink.rejects`: counting and logging rejected input;
- :mod:`~uavlink.mavlink.px4_modes`: PX4's flight-mode encoding;
- :mod:`~uavlink.mavlink.typemask`: SET_POSITION_TARGET_*'s type-mask bits;
- :mod:`~uavlink.mavlink.frames`: the MAV_FRAME sets (global, AMSL, relative) and the mission items' frame pairs;
- :mod:`~uavlink.mavlink.radio_codec`: how radio readings travel (DEBUG_FLOAT_ARRAY);
- :mod:`~uavlink.mavlink.ue_truth`: where the simulated UEs are (ADSB_VEHICLE), for pictures only;
- :mod:`~uavlink.mavlink.geo`: local NED <-> WGS-84 around an origin, as PX4's ``map_projection``;
- :mod:`~uavlink.mavlink.mission`: the mission protocol's client side and its item codec.

Nothing here imports the flight loop, the vehicle or the trainer; importing this package imports
no pymavlink (only :mod:`~uavlink.mavlink.dialect` does).

May import: ``errors``.
"""
