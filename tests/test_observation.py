"""The observation (uavlink/env/observation.py): its frame, declared once as a table of fields
from which size, names, bounds, slices and decoders follow; the env's encoding; layout checks."""

from __future__ import annotations

import numpy as np
import pytest

from uavlink.config import EnvConfig
from uavlink.env import BatchedUavEnv, ObservationLayout
from uavlink.env.observation import FIELDS, Field
from uavlink.evaluation import evaluate_policy
from uavlink.policies.baselines import AoaPolicy
from uavlink.radio import circular_mean_std_deg


def test_observation_layout_and_decoding():
    env = BatchedUavEnv(EnvConfig(scenario="hotspot").replace(aoa_noise_deg=5.0), n_envs=3, seed=1)
    layout = env.layout
    assert layout.frame_size == 2 + 10 + 3 and layout.size == 4 * 15
    names = layout.feature_names()
    assert len(names) == layout.size
    # Only what the base station senses: the UAV's own position, SINRs, AoA statistics.
    allowed = {"uav_x", "uav_y", "aoa_mean_sin", "aoa_mean_cos", "aoa_std"} | {
        f"sinr_{u}" for u in range(10)
    }
    assert {name.split(":")[1] for name in names} == allowed
    obs = env.reset()
    assert obs.shape == (3, layout.size) and obs.dtype == np.float32
    # A fresh episode fills every memory slot with the first frame.
    frames = obs.reshape(3, 4, -1)
    np.testing.assert_array_equal(frames, frames[:, :1].repeat(4, axis=1))
    rng = np.random.default_rng(0)
    previous = obs
    for _ in range(5):
        obs = env.step(rng.uniform(-1, 1, (3, 2))).observation
        readings = env.readings
        # The newest frame is exactly the encoding of (UAV position, SINR, AoA): nothing else.
        expected = layout.encode_frame(env.uav_xy_m, readings.sinr_db, readings.aoa_deg)
        np.testing.assert_allclose(obs[:, : layout.frame_size], expected, rtol=1e-6, atol=1e-6)
        # The older frames are the previous observation shifted by one frame.
        np.testing.assert_array_equal(
            obs[:, layout.frame_size :], previous[:, : 3 * layout.frame_size]
        )
        decoded = layout.newest_frame(obs)
        np.testing.assert_allclose(decoded["uav_xy_m"], env.uav_xy_m, atol=1e-4)
        np.testing.assert_allclose(
            decoded["sinr_db"], np.clip(readings.sinr_db, -30, 50), atol=1e-4
        )
        mean, std = circular_mean_std_deg(readings.aoa_deg)
        np.testing.assert_allclose(
            ((decoded["aoa_mean_deg"] - mean) + 180) % 360 - 180, 0, atol=1e-3
        )
        np.testing.assert_allclose(decoded["aoa_std_deg"], std, atol=1e-3)
        # The history decoders agree with the newest frame's decoding and with the encoding.
        np.testing.assert_allclose(layout.uav_xy_m_history(obs)[:, 0], decoded["uav_xy_m"])
        np.testing.assert_allclose(layout.sinr_db_history(obs)[:, 0], decoded["sinr_db"])
        np.testing.assert_allclose(
            layout.aoa_feature_history(obs)[:, 0], expected[:, -3:], atol=1e-6
        )
        np.testing.assert_array_equal(layout.frames(obs)[:, 1:], layout.frames(previous)[:, :-1])
        previous = obs


def test_layout_mismatch_names_both_layouts():
    policy_layout = ObservationLayout(memory=4)
    env_layout = ObservationLayout(memory=2)
    with pytest.raises(ValueError) as excinfo:
        policy_layout.check_matches(env_layout)
    message = str(excinfo.value)
    assert policy_layout.describe() in message and env_layout.describe() in message
    assert "memory=4" in message and "memory=2" in message and "\n" not in message
    policy_layout.check_matches(ObservationLayout.from_dict(policy_layout.to_dict()))  # equal: fine
    # Evaluating a policy built for another layout fails the same way.
    policy = AoaPolicy(EnvConfig(memory=4))
    with pytest.raises(ValueError, match=r"mismatch.*memory=4.*memory=2"):
        evaluate_policy(policy, EnvConfig(memory=2), episodes=1)


def test_the_field_table_drives_size_names_bounds_and_slices():
    layout = ObservationLayout(n_ues=3, memory=2, half_width_m=150.0)
    assert layout.fields == FIELDS
    assert [f.quantity for f in FIELDS] == ["uav_xy_m", "sinr_db", "aoa_mean_deg", "aoa_std_deg"]
    assert layout.frame_size == sum(f.width(layout) for f in FIELDS) == 2 + 3 + 2 + 1
    names, (low, high) = layout.feature_names(), layout.bounds()
    assert len(names) == len(low) == len(high) == layout.size == 2 * layout.frame_size
    assert low.dtype == high.dtype == np.float32
    for field in FIELDS:
        columns = layout.slices[field.quantity]
        assert [n.split(":")[1] for n in names[columns]] == field.names(layout)
        for lag in range(layout.memory):  # every frame in memory has the same columns
            shifted = slice(
                columns.start + lag * layout.frame_size, columns.stop + lag * layout.frame_size
            )
            assert all(n.startswith(f"t-{lag}:") for n in names[shifted])
            np.testing.assert_array_equal(low[shifted], np.float32(field.bounds(layout)[0]))
            np.testing.assert_array_equal(high[shifted], np.float32(field.bounds(layout)[1]))
    assert names[layout.slices["sinr_db"]] == ["t-0:sinr_0", "t-0:sinr_1", "t-0:sinr_2"]
    # The manifest's layout record is the dataclass's fields, not the table: shipped policies load.
    assert set(layout.to_dict()) == {
        "version",
        "n_ues",
        "memory",
        "half_width_m",
        "sinr_offset_db",
        "sinr_scale_db",
        "sinr_clip_db",
        "aoa_std_max_rad",
    }


def test_encode_then_decode_round_trips_every_field():
    layout = ObservationLayout(n_ues=4, memory=3)
    rng = np.random.default_rng(2)
    uav_xy_m = rng.uniform(-200, 200, (50, 2))
    sinr_db = rng.uniform(-60, 80, (50, 4))  # beyond the clip range on both sides
    aoa_deg = rng.uniform(-180, 180, (50, 4))
    encoded = layout.encode_frame(uav_xy_m, sinr_db, aoa_deg).astype(np.float32)
    low, high = layout.bounds()
    assert np.all(encoded >= low[: layout.frame_size]) and np.all(
        encoded <= high[: layout.frame_size]
    )
    obs = np.tile(encoded, (1, layout.memory))
    mean_deg, std_deg = circular_mean_std_deg(aoa_deg)
    physical = {
        "uav_xy_m": uav_xy_m,
        "sinr_db": np.clip(sinr_db, *layout.sinr_clip_db),
        "aoa_mean_deg": mean_deg,
        "aoa_std_deg": std_deg,
    }
    newest = layout.newest_frame(obs)
    assert set(newest) == set(physical)
    for quantity, value in physical.items():
        got = newest[quantity]
        if quantity == "aoa_mean_deg":
            got = ((got - value) + 180) % 360 - 180 + value  # an angle: equal modulo 360
        np.testing.assert_allclose(got, value, atol=1e-3, err_msg=quantity)
        history = layout.history(obs, quantity)
        assert history.shape == (50, layout.memory, *np.shape(value)[1:])
        np.testing.assert_array_equal(history[:, 0], newest[quantity])


class MeanSinrLayout(ObservationLayout):
    """A layout with one more per-UAV field: declaring it is the only change."""

    fields = (
        *FIELDS,
        Field(
            "sinr_db_mean",
            ("sinr_mean",),
            encode=lambda layout, q: (q["sinr_db"].mean(axis=1) / 100.0)[:, None],
            decode=lambda layout, x: x[..., 0] * 100.0,
            bounds=lambda layout: (-1.0, 1.0),
        ),
    )


def test_a_new_field_is_one_entry_in_the_table():
    base, extended = ObservationLayout(n_ues=2), MeanSinrLayout(n_ues=2)
    assert extended.frame_size == base.frame_size + 1 and extended.size == base.size + base.memory
    assert extended.feature_names()[base.frame_size] == "t-0:sinr_mean"
    sinr_db = np.array([[10.0, 30.0]])
    frame = extended.encode_frame(np.zeros((1, 2)), sinr_db, np.zeros((1, 2)))
    assert frame.shape == (1, extended.frame_size)
    obs = np.tile(frame, (1, extended.memory))
    np.testing.assert_allclose(extended.newest_frame(obs)["sinr_db_mean"], [20.0])
    np.testing.assert_allclose(
        extended.history(obs, "sinr_db")[:, 0], sinr_db
    )  # the others unmoved


def test_a_fleet_layout_adds_the_shared_fields_and_round_trips_them():
    from uavlink.env.observation import FLEET_FIELDS, fleet_quantities

    layout = ObservationLayout.for_config(EnvConfig(n_ues=3, n_uavs=3))
    assert layout.version == 2 and layout.fields == FIELDS + FLEET_FIELDS
    assert layout.frame_size == (2 + 3 + 2 + 1) + 2 * 2 + (2 + 1) + 3 * 3
    assert ObservationLayout.from_dict(layout.to_dict()) == layout
    assert layout.feature_names()[8:12] == [
        "t-0:other_x_1",
        "t-0:other_y_1",
        "t-0:other_x_2",
        "t-0:other_y_2",
    ]
    uav = np.array([[[0.0, 0.0], [50.0, 0.0], [0.0, 50.0]]])
    serving = np.array([[2, 0, 1]])
    shared = fleet_quantities(uav, serving)
    np.testing.assert_array_equal(
        shared["others_xy_m"][1], [[0.0, 50.0], [0.0, 0.0]]
    )  # UAV 1 sees 2, then 0
    np.testing.assert_array_equal(shared["served_by"], [[2, 0, 1], [1, 2, 0], [0, 1, 2]])
    aoa = np.array([[10.0, 20.0, 30.0]] * 3)
    frame = layout.encode_frame(uav[0], np.zeros((3, 3)), aoa, **shared)
    decoded = {
        f.quantity: f.decode(layout, frame[:, layout.slices[f.quantity]]) for f in layout.fields
    }
    np.testing.assert_allclose(decoded["others_xy_m"], shared["others_xy_m"])
    np.testing.assert_array_equal(decoded["served_by"], shared["served_by"])
    np.testing.assert_allclose(
        decoded["cell_aoa_mean_deg"], [20.0, 30.0, 10.0], atol=1e-4
    )  # its own cell
    empty = layout.encode_frame(
        uav[0], np.zeros((3, 3)), aoa, **fleet_quantities(uav, np.zeros((1, 3), int))
    )
    cell = layout.slices["cell_aoa_mean_deg"]
    np.testing.assert_array_equal(empty[1:, cell], 0.0)  # UAVs 1 and 2 serve nobody


def test_unknown_quantity_names_the_layouts():
    layout = ObservationLayout()
    obs = np.zeros((1, layout.size), np.float32)
    for lookup in (
        lambda: layout.history(obs, "nope"),
        lambda: layout.encoded_history(obs, "sinr_db", "nope"),
    ):
        with pytest.raises(
            KeyError,
            match="no quantity 'nope'.*its quantities: uav_xy_m, sinr_db, aoa_mean_deg, aoa_std_deg",
        ):
            lookup()
