"""Orbax checkpoints behind one small wrapper.

A checkpoint is one pytree (``{"params": ..., "opt_state": ..., "ema": ...,
"step": ...}`` in training) saved under ``<workdir>/checkpoints/<step>/``.
Orbax writes each step into a temporary folder and renames it when complete, so
an interrupted save never leaves a half-written checkpoint that a resume could
pick up; the last ``keep`` steps are kept.

Restoring takes a *target* pytree of the same structure (abstract
``jax.ShapeDtypeStruct`` leaves are fine) so that namedtuples (optax states)
and shardings come back exactly as saved.
"""

from __future__ import annotations

from pathlib import Path

import jax

__all__ = ["Checkpointer"]


class Checkpointer:
    """Save / restore training state under ``directory`` keeping the last ``keep`` steps."""

    def __init__(self, directory, keep: int = 3):
        import orbax.checkpoint as ocp

        self._ocp = ocp
        self.directory = Path(directory).absolute()
        self._manager = ocp.CheckpointManager(
            self.directory,
            options=ocp.CheckpointManagerOptions(
                max_to_keep=keep,
                create=True,
                enable_async_checkpointing=False,  # a finished save is on disk
                cleanup_tmp_directories=True,  # leftovers of an interrupted save
            ),
        )

    def latest_step(self) -> int | None:
        return self._manager.latest_step()

    def all_steps(self) -> list[int]:
        return list(self._manager.all_steps())

    def save(self, step: int, tree, *, force: bool = False) -> bool:
        """Save ``tree`` as ``step`` (no-op if that step exists, unless ``force``)."""
        if not force and step in self._manager.all_steps():
            return False
        saved = self._manager.save(step, args=self._ocp.args.StandardSave(tree), force=True)
        self._manager.wait_until_finished()
        return bool(saved)

    def restore(self, target, step: int | None = None):
        """Restore ``step`` (default: latest) into the structure of ``target``."""
        step = self.latest_step() if step is None else step
        if step is None:
            raise FileNotFoundError(f"no checkpoint in {self.directory}")
        abstract = jax.tree.map(_abstract, target)
        return self._manager.restore(step, args=self._ocp.args.StandardRestore(abstract))

    def close(self):
        self._manager.close()


def _abstract(x):
    if isinstance(x, jax.Array):
        return jax.ShapeDtypeStruct(x.shape, x.dtype, sharding=x.sharding)
    return x
