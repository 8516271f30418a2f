"""Grounding: from a scene and an instruction to the object the motion is for.

- :mod:`.objects`: the room's object table (given, or derived from a labelled scan), the
  objects a text names, their class mates.
- :mod:`.phrasing` (with the word lists of :mod:`.lexicon`, matched by :mod:`.words`): free
  phrasing read into the action, the target class, its relation to anchors ("plop down on
  the couch beside the cabinet", "sit at the desk"); :mod:`.similarity`: the sentence
  encoder's nearest action / class where the word lists run out.
- :mod:`.target`: the instruction read once (:class:`Instruction`), the candidates it may
  mean (named class or a stand-in, "the seat at the desk", narrowed by the scene graph's
  relations) with notes (:class:`Candidates`), and the chosen :class:`Target`.
- :mod:`.region`: the crop square the models see, chosen by the ADM's map among several
  candidates (or the room's tiles) when the text alone does not single one out.
- :mod:`.report`: what was understood, said plainly (:func:`explain`), with warnings.
- :mod:`.llm`: ``--grounding llm``, a language model choosing the target in two prompts over
  any OpenAI-compatible chat-completions endpoint (standard library only).

``jaxmotion generate --object ID`` skips the choice; the web app's click plugs in here.
"""

from jaxmotion.grounding.objects import (
                                         find_object,
                                         mentioned_objects,
                                         object_table,
                                         same_class_others,
)
from jaxmotion.grounding.region import AdmChooser, find_region
from jaxmotion.grounding.report import Understanding, explain
from jaxmotion.grounding.similarity import TextSimilarity
from jaxmotion.grounding.target import (
                                         Candidates,
                                         Instruction,
                                         Target,
                                         candidate_objects,
                                         ground_candidates,
                                         read_instruction,
)

__all__ = ["AdmChooser", "Candidates", "Instruction", "Target", "TextSimilarity",
           "Understanding", "candidate_objects", "explain", "find_object", "find_region",
           "ground_candidates", "mentioned_objects", "object_table", "read_instruction",
           "same_class_others"]
