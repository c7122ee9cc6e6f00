"""EnvConfig's own checks: field types (validate() uses replace()'s check), the memory of place's
finest grid, and a nested config's key."""

from __future__ import annotations

import pytest

from uavlink.config import AreaConfig, EnvConfig, RadioConfig
from uavlink.config.env import PLACE_CELL_MIN_M, PLACE_CELLS_ACROSS
from uavlink.errors import ConfigError


@pytest.mark.parametrize(
    ("cfg", "message"),
    [
        (EnvConfig(n_ues=10.0), "env.n_ues must be an integer, got 10.0"),
        (EnvConfig(n_ues=True), "env.n_ues must be an integer, got True"),
        (EnvConfig(n_ues="10"), "env.n_ues must be an integer, got '10'"),
        (EnvConfig(frame_s="1"), "env.frame_s must be a number, got '1'"),
        (EnvConfig(r_max_m=None), "env.r_max_m must be a number, got None"),
        (EnvConfig(scenario=3), "env.scenario must be a string, got 3"),
        (
            EnvConfig(radio=RadioConfig(shadowing="no")),
            "radio.shadowing must be true or false, got 'no'",
        ),
        (
            EnvConfig(radio=RadioConfig(fast_fading=0)),
            "radio.fast_fading must be true or false, got 0",
        ),
        (
            EnvConfig(radio=RadioConfig(n_resource_blocks=50.0)),
            "radio.n_resource_blocks must be an integer, got 50.0",
        ),
        (
            EnvConfig(area=AreaConfig(half_width_m="200")),
            "area.half_width_m must be a number, got '200'",
        ),
        (
            EnvConfig(area={"half_width_m": 100}),
            "area must be an AreaConfig, got {'half_width_m': 100}",
        ),
        (EnvConfig(radio=AreaConfig()), "radio must be a RadioConfig, got AreaConfig("),
    ],
)
def test_validate_refuses_a_value_of_the_wrong_type_naming_the_field(
    cfg: EnvConfig, message: str
) -> None:
    with pytest.raises(ConfigError) as info:
        cfg.validate()
    assert str(info.value).startswith(message) and "\n" not in str(info.value)


def test_validate_and_replace_check_types_with_the_same_code() -> None:
    for key, value in [
        ("n_ues", 5.0),
        ("n_ues", True),
        ("radio.shadowing", "no"),
        ("frame_s", "1"),
    ]:
        with pytest.raises(ConfigError) as by_replace:
            EnvConfig().replace(**{key: value})
        head, _, tail = key.partition(".")
        nested = (
            {head: getattr(EnvConfig(), head).__class__(**{tail: value})} if tail else {key: value}
        )
        with pytest.raises(ConfigError) as by_validate:
            EnvConfig(**nested).validate()
        assert str(by_validate.value).endswith(
            str(by_replace.value)
        )  # "env.n_ues ..." vs "n_ues ..."
    with pytest.raises(ConfigError, match="radio.shadowing must be true or false"):
        RadioConfig(shadowing="no").validate()
    with pytest.raises(ConfigError, match="area.uav_altitude_m must be a number"):
        AreaConfig(uav_altitude_m=[95]).validate()


def test_ints_for_float_fields_and_the_declared_types_stay_accepted() -> None:
    cfg = EnvConfig(
        frame_s=1,
        r_max_m=12,
        place_cell_m=12,
        ue_speed_mps=0,
        cluster_size_m=10,
        area=AreaConfig(half_width_m=200, uav_altitude_m=95),
        radio=RadioConfig(bandwidth_hz=10_000_000, tx_power_dbm=19, aoa_noise_deg=0),
    )
    assert cfg.validate() is cfg
    assert EnvConfig().validate() == EnvConfig()
    assert EnvConfig().replace(r_max_m=8).r_max_m == 8.0  # replace still makes it a float


@pytest.mark.parametrize("cell_m", [1e-3, 0.5, 0.999])
def test_a_memory_of_place_finer_than_a_metre_is_refused_in_one_line(cell_m: float) -> None:
    with pytest.raises(ConfigError) as info:
        EnvConfig(place_cell_m=cell_m).validate()
    assert str(info.value) == (
        f"env.place_cell_m must be 0 (off) or >= 1 m (cells of at least 1 m, at most "
        f"400 across the area's 400 m), got {cell_m!r}"
    )


def test_the_finest_grid_is_at_most_400_cells_across_the_area() -> None:
    assert (PLACE_CELL_MIN_M, PLACE_CELLS_ACROSS) == (1.0, 400)
    for cell_m in (
        0.0,
        1.0,
        6.0,
        12.0,
        12,
        200.0,
    ):  # off, the bound, the shipped grids, the largest
        EnvConfig(place_cell_m=cell_m).validate()
    wide = AreaConfig(half_width_m=1000.0)  # 2000 m across: cells of at least 5 m
    EnvConfig(place_cell_m=5.0, area=wide).validate()
    with pytest.raises(
        ConfigError, match=r"place_cell_m must be 0 \(off\) or >= 5 m .* area's 2000 m\), got 4\.0"
    ):
        EnvConfig(place_cell_m=4.0, area=wide).validate()
    with pytest.raises(ConfigError, match="env.place_cell_m must be >= 0"):
        EnvConfig(place_cell_m=-1.0).validate()


def test_a_nested_config_key_says_what_it_takes() -> None:
    with pytest.raises(ConfigError) as info:
        EnvConfig().replace(area={"half_width_m": 100})
    assert str(info.value) == (
        "area is a nested config: pass an AreaConfig, or set its fields one by one "
        "(area.half_width_m=...), got {'half_width_m': 100}"
    )
    with pytest.raises(
        ConfigError,
        match=r"radio is a nested config: pass a RadioConfig, .*\(radio\.carrier_ghz=\.\.\.\)",
    ):
        EnvConfig().replace(radio=5)
    assert EnvConfig().replace(area=AreaConfig(half_width_m=100)).area.half_width_m == 100
    assert EnvConfig().replace(**{"area.half_width_m": 100}).area.half_width_m == 100.0
    with pytest.raises(ConfigError, match="unknown config key 'warp_drive'"):
        EnvConfig().replace(warp_drive=1)
