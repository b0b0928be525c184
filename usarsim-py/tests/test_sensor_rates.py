"""Sensor rates per sensor and the physics rate (issue #54, item 2; docs/python.md#sensor-rates),
and per-rotor actions on the quadrotor."""

import gymnasium
import numpy as np
import pytest

import usarsim


def test_a_quadrotor_env_with_per_rotor_actions_steps():
    env = gymnasium.make("usarsim/Hover-v0", robot="stsQuadrotor", action_mode="rotors", max_steps=50)
    obs, _ = env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(60):
        obs, reward, term, trunc, info = env.step(rng.uniform(-1, 1, 4).astype(np.float32))
        assert np.isfinite(reward) and all(np.isfinite(v).all() for v in obs.values())
        if term or trunc:
            obs, _ = env.reset()
    # With a fast IMU on 1 kHz physics, in the vector env and the multi-UAV env too.
    env = gymnasium.make("usarsim/Hover-v0", robot="stsQuadrotor", action_mode="rotors", physics_rate=1000,
                         sensor_rates={"IMU": 500})
    env.reset(seed=1)
    hover = (705.7 - 100) / 900 * 2 - 1
    for _ in range(10):
        obs, *_ = env.step(np.full(4, hover, np.float32))
        assert env.unwrapped.imu_readings().shape == (50, 7)
    venv = usarsim.vector_env(2, "hover", robot="stsQuadrotor", action_mode="rotors", physics_rate=1000,
                              sensor_rates={"IMU": 1000})
    venv.reset(seed=0)
    for _ in range(5):
        venv.step(venv.action_space.sample())
    multi = usarsim.multi_uav(2, "hover", robot="stsQuadrotor", action_mode="rotors", physics_rate=400,
                              sensor_rates={"IMU": 400})
    multi.reset(seed=0)
    for _ in range(5):
        multi.step({a: np.full(4, hover, np.float32) for a in multi.agents})


def test_an_imu_at_500_hz_gives_50_readings_per_tenth_of_a_second():
    env = gymnasium.make("usarsim/Hover-v0", robot="stsQuadrotor", period=0.1, physics_rate=1000,
                         sensor_rates={"IMU": 500})
    env.reset(seed=0)
    env.step(np.zeros(4, np.float32))
    imu = env.unwrapped.imu_readings()
    assert imu.shape == (50, 7)
    assert np.allclose(np.diff(imu[:, 0]), 0.002, atol=1e-6)
    assert np.isfinite(imu).all()
    assert abs(np.mean(imu[:, 3]) - 9.81) < 1.0  # hover: the specific force holds the weight
    # The default: 10 Hz, one reading a period.
    env = gymnasium.make("usarsim/Hover-v0", robot="stsQuadrotor")
    env.reset(seed=0)
    env.step(np.zeros(4, np.float32))
    assert env.unwrapped.imu_readings().shape == (1, 7)


@pytest.mark.parametrize("options, message", [
    (dict(sensor_rates={"IMU": 500}),
     r"sensor_rates: robot USARBot.stsQuadrotor: sensor IMU: rate 500 Hz \(interval 0.002 s\) is above the "
     r"physics rate of 200 Hz"),
    (dict(sensor_rates={"IMU": 150}), r"robot USARBot.stsQuadrotor: sensor IMU: rate 150 Hz .*not a whole number"),
    (dict(sensor_rates={"IMU": -5}), r"robot USARBot.stsQuadrotor: sensor IMU: the rate must be a positive number "
                                     r"of Hz, got -5"),
    (dict(sensor_rates={"IMU": 0}), r"sensor IMU: the rate must be a positive number of Hz, got 0"),
    (dict(sensor_rates={"IMU": float("nan")}), r"sensor IMU: the rate must be a positive number of Hz, got NaN"),
    (dict(sensor_rates={"IMU": "fast"}), r"sensor_rates: sensor IMU: the rate 'fast' is not a number of Hz"),
    (dict(sensor_rates={"Lidar": 5}), r"robot USARBot.stsQuadrotor: no sensor named \"Lidar\""),
    (dict(physics_rate=5000), r"physics_rate: the physics rate must be a number of Hz from 1 to 1000, got 5000"),
    (dict(physics_rate="fast"), r"physics_rate: expected a number of Hz, got 'fast'"),
    (dict(physics_rate=1000, period=0.0015), r"period: the control period must be a whole multiple of the 0.001 s"),
])
def test_bad_rates_name_the_robot_the_sensor_and_the_value(options, message):
    with pytest.raises(ValueError, match=message):
        gymnasium.make("usarsim/Hover-v0", robot="stsQuadrotor", **options)


NAV = """
[[robot]]
class = "USARBot.NavQuad"
dynamics = "quadrotor"
battery = 1200.0
[[robot.part]]
type = "Position"
name = "Position"
[[robot.part]]
type = "Velocity"
name = "Velocity"
[[robot.part]]
type = "IMU"
name = "IMU"
[[robot.part]]
type = "GPS"
name = "GPS"
interval = 0.2
error = { noise = 1.0, latency = 0.2 }
[[robot.part]]
type = "Magnetometer"
name = "Mag"
error = { noise = 0.2 }
"""


def test_a_robot_file_with_gps_and_magnetometer_needs_a_map_origin(tmp_path):
    robots = tmp_path / "nav.toml"
    robots.write_text(NAV)
    with pytest.raises(ValueError, match=r"map: robot USARBot.NavQuad: sensor GPS: a GPS needs the map's origin "
                                         r"\(`\[geo\]` latitude and longitude, docs/maps.md#geo\); map EmptyRoom has none"):
        gymnasium.make("usarsim/Hover-v0", robot="NavQuad", robots=str(robots))
    root = __import__("pathlib").Path(__file__).resolve().parents[2]
    geo_map = tmp_path / "geo_room.toml"
    geo_map.write_text((root / "usar-sim/maps/empty_room.toml").read_text()
                       + "\n[geo]\nlatitude = 47.5\nlongitude = -122.25\n")
    env = gymnasium.make("usarsim/Hover-v0", robot="NavQuad", robots=str(robots), map=str(geo_map),
                         action_mode="rotors", physics_rate=1000, sensor_rates={"IMU": 1000, "GPS": 5})
    env.reset(seed=0)
    for _ in range(5):
        env.step(np.full(4, 0.346, np.float32))
        assert env.unwrapped.imu_readings().shape == (100, 7)
    with pytest.raises(ValueError, match=r"robots: .*nowhere.toml"):
        gymnasium.make("usarsim/Hover-v0", robots=str(tmp_path / "nowhere.toml"))
