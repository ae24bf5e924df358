"""The smallest plant the diagnosis tests fit: a measured position that follows its command."""
import numpy as np


def first_order_lag(cmd, Ts, seed=0):
    """The position of a first-order lag (60 rad/s) driven by the command one sample late, with
    10 nm of encoder noise (``seed``), [mm]."""
    act = np.empty(cmd.size)
    act[0] = cmd[0]
    a = np.exp(-Ts * 60)
    for k in range(1, cmd.size):
        act[k] = a * act[k - 1] + (1 - a) * cmd[k - 1]
    return act + np.random.default_rng(seed).normal(0, 1e-5, cmd.size)
