"""Grounding: from a scene and an instruction to the object the motion is for.

- :mod:`.objects`: the room's object table (given, or derived from a labelled scan), the
  objects a text names, their class mates.
- :mod:`.target`: the instruction read once (:class:`Instruction`), the candidates it may
  mean (narrowed by the scene graph's relations), and the chosen :class:`Target`.
- :mod:`.region`: the crop square the models see, chosen by the ADM's map among several
  candidates (or the room's tiles) when the text alone does not single one out.

``jaxmotion generate --object ID`` skips the choice; a language-model grounder and the web
app's click plug in here.
"""

from jaxmotion.grounding.objects import (
                                         find_object,
                                         mentioned_objects,
                                         object_table,
                                         same_class_others,
)
from jaxmotion.grounding.region import AdmChooser, find_region
from jaxmotion.grounding.target import Instruction, Target, candidate_objects, read_instruction

__all__ = ["AdmChooser", "Instruction", "Target", "candidate_objects", "find_object",
           "find_region", "mentioned_objects", "object_table", "read_instruction",
           "same_class_others"]
