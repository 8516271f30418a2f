"""Write the sentence encoder's embeddings of the reader's action prototypes and class names
(``jaxmotion/grounding/data/phrase_embeddings.npz``; see :mod:`jaxmotion.grounding.similarity`).

Run it after changing ``ACTION_PROTOTYPES`` or the class lists, or to ship the table for
other encoder weights:

    python scripts/make_phrase_table.py [PATH]
"""

import sys

from jaxmotion.grounding.similarity import table_phrases, write_phrase_table

if __name__ == "__main__":
    path = write_phrase_table(*sys.argv[1:2])
    print(f"wrote {len(table_phrases())} phrase embeddings to {path}")
