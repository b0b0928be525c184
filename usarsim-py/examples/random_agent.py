"""A random agent on usarsim/Waypoints-v0; writes the last frame as a PPM picture."""

import gymnasium
import numpy as np

import usarsim  # noqa: F401  (registers the environments)

env = gymnasium.make("usarsim/Waypoints-v0", render_mode="rgb_array")
obs, info = env.reset(seed=0)
total = 0.0
for t in range(200):
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    total += reward
    if terminated or truncated:
        break
print(f"{t + 1} steps, return {total:.2f}, waypoints reached {info['waypoints_reached']}")
frame = env.render()
with open("random_agent.ppm", "wb") as f:
    f.write(b"P6 %d %d 255\n" % (frame.shape[1], frame.shape[0]) + frame.tobytes())
print("last frame: random_agent.ppm")
