"""Training: ``python -m jaxmotion.train --config configs/<name>.py [key=value ...]``.

:mod:`~jaxmotion.train.loop` is the model-agnostic loop (optimiser, EMA, data
parallelism, Orbax checkpoints, logs); :mod:`~jaxmotion.train.tasks` defines what
each config trains.
"""

from jaxmotion.train.checkpoint import Checkpointer
from jaxmotion.train.config import DiffusionConfig, OptimConfig, TrainConfig
from jaxmotion.train.loop import Task, TrainResult, load_trained, make_optimizer, train

__all__ = [
    "Checkpointer", "DiffusionConfig", "OptimConfig", "Task", "TrainConfig", "TrainResult",
    "load_trained", "make_optimizer", "train",
]
