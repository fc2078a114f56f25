"""The simulator's run log: the ground-truth track of every robot at whole simulated seconds."""

import numpy as np

from swarm_common.stamps import NS_PER_S
from swarm_sim.standstill import StandstillTracker
from swarm_sim.summary import RunLog


def test_the_track_keeps_every_robots_position_at_each_whole_second_to_the_centimetre():
    poses = np.array([[1.234, -2.345, 0.5], [0.0, 0.001, 3.0]])
    log = RunLog(StandstillTracker(poses))
    for tick in range(1, 26):  # 0.1 s ticks up to 2.5 s
        log.sample(tick * NS_PER_S // 10, poses + [0.1 * tick, 0.0, 0.0])
    assert [xy.tolist() for xy in log.track] == [[[2.23, -2.35], [1.0, 0.0]],
                                                [[3.23, -2.35], [2.0, 0.0]]]
    log.sample(0, poses)  # the start is no sample
    assert len(log.track) == 2
