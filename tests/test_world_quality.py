"""The issue's motion-quality criteria on 200 samples of the real synthetic world
(rooms from jaxmotion.scene, tasks from its instruction generator, motions from the
kinematic character): the same path `jaxmotion synth` takes."""

import numpy as np
import pytest

from jaxmotion.motion import MotionError, synthesize
from jaxmotion.scene import NoUniqueReference, sample_room, sample_task

from test_motion import check  # the per-motion acceptance checks


@pytest.mark.slow
def test_quality_on_200_world_samples():
    rng = np.random.default_rng(7)
    done, failures, actions = 0, 0, {}
    while done < 200:
        room = sample_room(rng)
        for _ in range(2):  # two tasks per room
            try:
                _, info = sample_task(room, rng)
                target = room.object(info["target_id"])
                m = synthesize(info["action"], room.floor_rects, room.objects, target["id"], rng)
            except (MotionError, NoUniqueReference):
                failures += 1
                continue
            check(m, list(room.objects), target)
            actions[m.action] = actions.get(m.action, 0) + 1
            done += 1
    assert failures <= 0.15 * done, failures  # resampling in the builder stays cheap
    assert set(actions) == {"walk", "sit", "stand_up", "lie"}, actions
