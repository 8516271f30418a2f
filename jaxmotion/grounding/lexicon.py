"""The words :mod:`jaxmotion.grounding.phrasing` reads instructions with: data, no logic.

Every phrase is written in lower-case ASCII with its verbs in their base form ("sit", not
"sitting": the reader lemmatises the text's verbs first, :data:`VERB_FORMS`). The four
actions are jaxmotion's (HUMANISE's): ``walk``, ``sit``, ``stand_up``, ``lie``. Object
classes are the synthetic world's (:data:`jaxmotion.scene.furniture.CATEGORY_IDS`) and the
NYU40 names of labelled scans; relations are the scene graph's
(:data:`jaxmotion.scene.graph.RELATIONS`).

Where these lists run out, :mod:`jaxmotion.grounding.similarity` compares the text with the
prototypes below (:data:`ACTION_PROTOTYPES`) by the sentence encoder's cosine.
"""

from __future__ import annotations

__all__ = ["ACTION_PHRASES", "ACTION_PROTOTYPES", "ANCHOR_SIDES", "CATEGORY_WORDS",
           "CLAUSE_BREAKS", "DETERMINERS", "DIRECT_PREPOSITIONS", "FILLER", "GENERIC_TARGETS",
           "IDIOMS", "NEGATIONS", "PARTICIPLES", "RELATED", "RELATION_PHRASES", "ROOM_WORDS",
           "SEAT_AT", "SUPERLATIVES", "UNSUPPORTED_RELATIONS", "VERB_FORMS", "WEAK_VERBS"]

# --------------------------------------------------------------------------- objects
#: canonical class -> the words people use for it (the class name itself included).
CATEGORY_WORDS: dict[str, tuple[str, ...]] = {
    "chair": ("chair", "desk chair", "office chair", "dining chair", "kitchen chair",
              "computer chair", "side chair", "wooden chair", "folding chair", "rocking chair",
              "swivel chair", "straight chair"),
    "armchair": ("armchair", "arm chair", "easy chair", "lounge chair", "club chair",
                 "wing chair", "wingback chair", "wingback", "recliner", "reclining chair",
                 "accent chair", "lazy boy", "lazyboy"),
    "sofa": ("sofa", "couch", "settee", "loveseat", "love seat", "davenport", "divan",
             "chesterfield", "futon couch", "sectional", "sofa bed", "bench"),
    "stool": ("stool", "bar stool", "barstool", "footstool", "foot stool", "step stool",
              "ottoman", "pouf", "pouffe", "tabouret"),
    "bed": ("bed", "mattress", "bunk", "bunk bed", "double bed", "single bed", "king bed",
            "queen bed", "twin bed", "cot", "futon", "daybed", "day bed"),
    "toilet": ("toilet", "loo", "wc", "lavatory", "commode", "toilet seat"),
    "table": ("table", "dining table", "kitchen table", "side table", "end table",
              "dinner table", "round table", "square table", "breakfast table"),
    "coffee table": ("coffee table", "cocktail table", "low table", "tea table"),
    "desk": ("desk", "writing desk", "work desk", "office desk", "computer desk", "workstation",
             "bureau", "study desk", "worktable", "work table"),
    "nightstand": ("nightstand", "night stand", "bedside table", "bedside cabinet",
                   "night table", "bedside stand", "bedside"),
    "cabinet": ("cabinet", "cupboard", "wardrobe", "closet", "armoire", "sideboard",
                "credenza", "tv stand", "tv cabinet", "chest of drawers", "drawers", "cabinets",
                "filing cabinet", "locker"),
    "bookshelf": ("bookshelf", "bookcase", "book shelf", "book case", "shelving unit",
                  "bookshelves", "shelf"),
    "door": ("door", "doorway", "door way", "entrance", "entry", "exit", "front door",
             "doorframe", "door frame"),
    "window": ("window", "windowsill", "window sill", "windows"),
    "picture": ("picture", "painting", "photo", "photograph", "poster", "artwork", "art",
                "framed picture", "portrait"),
    "sink": ("sink", "washbasin", "wash basin", "basin", "hand basin", "washbowl",
             "kitchen sink", "bathroom sink", "vanity"),
    "fridge": ("fridge", "refrigerator", "icebox", "ice box", "freezer", "frigerator"),
    "lamp": ("lamp", "floor lamp", "table lamp", "desk lamp", "standing lamp", "reading lamp",
             "light", "lampshade", "lamp shade", "bedside lamp"),
    "tv": ("tv", "television", "telly", "tv set", "television set", "flatscreen",
           "flat screen", "monitor", "screen"),
    # NYU40 classes of labelled scans (ScanNet), with a few words of their own
    "counter": ("counter", "countertop", "counter top", "kitchen counter", "worktop",
                "kitchen island", "island", "bar"),
    "shelves": ("shelves", "shelving", "rack"),
    "dresser": ("dresser", "chest", "vanity table"),
    "curtain": ("curtain", "curtains", "drapes"),
    "blinds": ("blinds", "blind", "shades"),
    "mirror": ("mirror",),
    "pillow": ("pillow", "cushion"),
    "floor mat": ("floor mat", "rug", "carpet", "mat", "doormat"),
    "clothes": ("clothes", "clothing"),
    "books": ("books", "book"),
    "paper": ("paper", "papers"),
    "towel": ("towel",),
    "shower curtain": ("shower curtain",),
    "box": ("box", "crate", "carton"),
    "whiteboard": ("whiteboard", "white board", "blackboard", "chalkboard"),
    "bathtub": ("bathtub", "bath tub", "tub", "bath"),
    "bag": ("bag", "backpack", "suitcase"),
}
#: words for "any seat" / "anything to lie on": the action's own classes.
GENERIC_TARGETS: dict[str, str] = {
    "seat": "sit", "seats": "sit", "seating": "sit", "somewhere to sit": "sit",
    "somewhere to sit down": "sit", "something to sit on": "sit", "a place to sit": "sit",
    "place to sit": "sit", "spot to sit": "sit",
    "somewhere to lie": "lie", "somewhere to lie down": "lie", "something to lie on": "lie",
    "place to lie down": "lie", "somewhere to sleep": "lie", "place to sleep": "lie",
}
#: classes to use, in this order, when the room has none of the named one ("the table" in
#: a room with a coffee table only).
RELATED: dict[str, tuple[str, ...]] = {
    "table": ("coffee table", "desk", "counter"), "coffee table": ("table",),
    "desk": ("table", "counter"), "counter": ("table", "desk"),
    "chair": ("armchair", "stool"), "armchair": ("chair", "sofa"), "stool": ("chair",),
    "sofa": ("armchair",), "nightstand": ("dresser", "cabinet", "table"),
    "cabinet": ("dresser", "shelves", "bookshelf"), "dresser": ("cabinet", "nightstand"),
    "bookshelf": ("shelves", "cabinet"), "shelves": ("bookshelf", "cabinet"),
    "lamp": (), "tv": (), "picture": ("mirror", "whiteboard"), "sink": (), "fridge": (),
}
#: classes one sits *at* ("sit at the desk": the seat nearest it).
SEAT_AT = ("desk", "table", "coffee table", "counter", "dresser")

# --------------------------------------------------------------------------- actions
#: verb phrases (base forms) -> action, longest match first. "stand" alone is walking to a
#: place ("stand next to the door"); "stand up" is getting up.
ACTION_PHRASES: dict[str, str] = {
    # getting up
    **dict.fromkeys((
        "stand up", "stand back up", "get up", "get back up", "rise", "rise up", "arise",
        "get off", "get out of", "climb out of", "climb off", "hop off", "jump off",
        "hop up", "jump up", "spring up", "pull yourself up", "push yourself up",
        "lift yourself up", "get to your foot", "rise to your foot", "stand up off",
        "stop sit", "quit sit", "up from", "get yourself up", "haul yourself up",
        "come up off", "stand off", "step off", "leave your seat", "vacate"), "stand_up"),
    # lying down
    **dict.fromkeys((
        "lie", "lie down", "lie back", "lie flat", "lay", "lay down", "lay yourself down",
        "stretch out", "stretch yourself out", "stretch", "have a nap", "take a nap", "nap",
        "have a snooze", "take a snooze", "snooze", "sleep", "go to sleep", "fall asleep",
        "doze", "doze off", "nod off", "curl up", "hit the sack", "hit the hay",
        "have a lie down", "have a lie", "crash", "sprawl", "sprawl out", "bed down",
        "tuck yourself in", "kip", "have a kip", "catch some sleep", "get some sleep",
        "get some rest", "take a rest", "have a rest", "get horizontal", "lay flat",
        "put your head down", "lay your head down", "rest your head", "get some shut eye",
        "catch forty winks", "catch some z", "forty winks", "snuggle up", "snuggle",
        "cuddle up", "take a siesta", "have a siesta", "siesta"), "lie"),
    # sitting down
    **dict.fromkeys((
        "sit", "sit down", "sit back", "sit yourself down", "seat yourself", "be seat",
        "take a seat", "have a seat", "grab a seat", "find a seat", "get a seat", "take seat",
        "take a load off", "plop", "plop down", "plop yourself down", "plonk",
        "plonk yourself down", "plunk down", "park yourself", "park it", "park your butt",
        "park your bum", "perch", "perch yourself", "squat", "sink into", "sink down",
        "rest your leg", "rest your foot", "take the weight off", "sit your butt",
        "hop on", "hop onto", "get on", "climb on", "climb onto", "settle into",
        "settle down", "settle in", "slump", "slump down", "drop down", "drop into"), "sit"),
    # walking
    **dict.fromkeys((
        "walk", "walk over", "walk up", "go", "go over", "go up", "head", "head over",
        "move", "approach", "step", "step over", "stroll", "wander", "amble", "saunter",
        "stride", "make your way", "find your way", "wend your way", "come", "come over",
        "run", "jog", "hurry", "rush", "dash", "pace", "march", "tiptoe", "trot", "shuffle",
        "get over", "get to", "reach", "proceed", "navigate", "travel", "visit", "stand",
        "hop over", "pop over", "nip over", "cross the room", "cross", "find", "check out",
        "head toward", "make a beeline", "walk across", "stop", "wait", "end up",
        "position yourself", "go stand", "limp", "sprint", "creep", "sneak", "go and stand",
        "follow the path", "get closer", "move closer", "come closer", "get near"), "walk"),
}
#: verbs whose action depends on the object: ``rest``-like ones are lying on a bed and
#: sitting on another seat; ``leave``-like ones are getting up from a seat or bed. On
#: anything else, or without an object, they are not read as one of the four actions.
WEAK_VERBS: dict[str, str] = {
    **dict.fromkeys(("rest", "relax", "chill", "chill out", "unwind", "lounge", "flop",
                     "flop down", "collapse", "recline", "get comfortable", "settle",
                     "put your foot up", "kick back", "loaf", "laze", "rest up"), "rest"),
    **dict.fromkeys(("leave", "get away from", "get away"), "leave"),
}
#: phrases naming an object inside the verb: (action, class or None).
IDIOMS: dict[str, tuple[str, str | None]] = {
    "go to bed": ("lie", "bed"), "get into bed": ("lie", "bed"), "get in bed": ("lie", "bed"),
    "climb into bed": ("lie", "bed"), "hop into bed": ("lie", "bed"),
    "jump into bed": ("lie", "bed"), "crawl into bed": ("lie", "bed"),
    "get out of bed": ("stand_up", "bed"), "climb out of bed": ("stand_up", "bed"),
    "roll out of bed": ("stand_up", "bed"), "hop out of bed": ("stand_up", "bed"),
    "jump out of bed": ("stand_up", "bed"), "get off the bed": ("stand_up", "bed"),
    "pull up a chair": ("sit", None), "pull up a seat": ("sit", None),
    "take a seat": ("sit", None), "have a seat": ("sit", None), "grab a seat": ("sit", None),
    "find a seat": ("sit", None), "get a seat": ("sit", None), "leave your seat":
    ("stand_up", None), "take the weight off your foot": ("sit", None),
}
#: verbs' inflected forms -> base form (regular -s / -ed / -ing forms are derived).
VERB_FORMS: dict[str, str] = {
    "sat": "sit", "sitting": "sit", "seated": "seat", "lying": "lie", "lain": "lie",
    "laid": "lay", "laying": "lay", "stood": "stand", "got": "get", "gotten": "get",
    "getting": "get", "went": "go", "gone": "go", "goes": "go", "going": "go", "ran": "run",
    "running": "run", "came": "come", "coming": "come", "rose": "rise", "risen": "rise",
    "rising": "rise", "slept": "sleep", "napping": "nap", "napped": "nap", "stepping": "step",
    "stepped": "step", "plopping": "plop", "plopped": "plop", "jogging": "jog",
    "jogged": "jog", "dropping": "drop", "dropped": "drop", "feet": "foot", "legs": "leg",
    "left": "left", "sank": "sink", "sunk": "sink", "hopping": "hop", "hopped": "hop",
    "stopping": "stop", "stopped": "stop", "made": "make", "found": "find", "took": "take",
    "taken": "take", "had": "have", "has": "have", "having": "have", "fell": "fall",
    "fallen": "fall", "hung": "hang", "hanging": "hang", "dozing": "doze", "dozed": "doze",
    "leaving": "leave", "sprinting": "sprint", "strode": "stride", "striding": "stride",
    "crept": "creep", "creeping": "creep", "held": "hold", "holding": "hold",
    "placed": "place", "located": "locate", "situated": "situate", "positioned": "position",
    "lies": "lie", "lay": "lay", "is": "be", "are": "be", "was": "be", "were": "be",
    "settling": "settle", "settled": "settle", "relaxing": "relax", "resting": "rest",
    "rested": "rest", "lounging": "lounge", "reclining": "recline", "moving": "move",
    "moved": "move", "approaching": "approach", "approached": "approach",
}
#: participles that, right after an object's name, describe it ("the lamp sitting on
#: the table", "the picture hanging above the bed") instead of asking for an action.
PARTICIPLES = ("sitting", "standing", "lying", "laying", "resting", "hanging", "placed",
               "located", "situated", "positioned", "sat", "set", "mounted", "perched",
               "leaning", "stood", "found", "kept", "put")
#: words after which a verb phrase is not asked for ("don't sit, walk to the chair").
NEGATIONS = ("not", "never", "dont", "without", "instead of", "rather than")

#: sentences per action whose sentence-encoder embeddings the verb phrase is compared with
#: when no phrase above is found (:mod:`jaxmotion.grounding.similarity`).
ACTION_PROTOTYPES: dict[str, tuple[str, ...]] = {
    "walk": ("walk over to it", "go over there", "walk there", "move towards it", "approach it",
             "go to it", "walk", "come over to it", "hurry over to it", "stroll to it"),
    "sit": ("sit down on it", "take a seat", "sit down", "have a seat", "sit", "sit on it"),
    "stand_up": ("stand up from it", "get up", "rise to your feet", "stand up",
                 "get up off it"),
    "lie": ("lie down on it", "lie down", "go to sleep", "take a nap", "lie", "sleep on it",
            "lie down and rest"),
}

# --------------------------------------------------------------------------- relations
#: relation phrases (base forms) -> scene-graph relation, longest match first.
RELATION_PHRASES: dict[str, str] = {
    **dict.fromkeys(("between", "in between", "halfway between", "in the middle of",
                     "midway between", "in the middle between"), "between"),
    **dict.fromkeys(("with", "that have", "which have", "that hold", "which hold", "hold",
                     "support", "supporting", "carry", "that the", "which the", "have",
                     "underneath which", "bearing"), "supporting"),
    **dict.fromkeys(("farthest from", "furthest from", "farthest away from",
                     "furthest away from", "far from", "far away from", "away from",
                     "most distant from", "farthest", "furthest", "across the room from",
                     "at the far end from", "on the far side of the room from",
                     "at the other end of the room from", "as far as possible from"),
                    "farthest"),
    **dict.fromkeys(("closest to", "nearest to", "nearest", "closest", "next to",
                     "right next to", "right by", "close to", "close by", "near", "near to",
                     "nearby", "beside", "besides", "alongside", "by", "at", "adjacent to",
                     "against", "by the side of", "to the side of", "in front of",
                     "right in front of", "across from", "opposite", "opposite to",
                     "opposite of", "facing", "that face", "which face", "behind",
                     "in back of", "at the back of", "around", "at the foot of",
                     "at the end of", "next door to", "neighbouring", "neighboring",
                     "closer to", "nearer to", "that be closest to",
                     "that be nearest to", "that be next to", "that be near"), "closest"),
    **dict.fromkeys(("on top of", "on", "upon", "onto", "stand on", "sit on", "rest on",
                     "place on", "lie on", "set on", "that be on", "sitting on",
                     "standing on", "perched on", "put on", "atop"), "on"),
    **dict.fromkeys(("above", "over", "hang above", "hang over", "mounted above",
                     "mount above", "up above", "hanging above", "hanging over"), "above"),
    **dict.fromkeys(("below", "beneath", "underneath", "under", "underneath of",
                     "down below"), "below"),
}
#: relation phrases that also ask for a side of the anchor where it has a front.
ANCHOR_SIDES: dict[str, str] = {
    "in front of": "front", "right in front of": "front", "across from": "front",
    "opposite": "front", "opposite to": "front", "opposite of": "front", "facing": "front",
    "that face": "front", "which face": "front", "behind": "back",
    "in back of": "back", "at the back of": "back",
}
#: superlatives before the object's name ("the nearest chair to the door").
SUPERLATIVES = {"nearest": "closest", "closest": "closest", "farthest": "farthest",
                "furthest": "farthest"}
#: relation words the scene graph has no relation for, and what the reader says of them.
UNSUPPORTED_RELATIONS = ("to the left of", "to the right of", "left of", "right of",
                         "on the left of", "on the right of", "on the left side of",
                         "on the right side of", "to the left", "to the right",
                         "on the left", "on the right", "at the left", "at the right",
                         "on your left", "on your right", "left", "right", "inside",
                         "in the corner", "in the middle of the room", "in the center",
                         "in the centre")

# --------------------------------------------------------------------------- the rest
#: words for the room itself or a kind of room: "dance around the kitchen", "sit down in the
#: living room" name no object (the action is done in the room the user gave).
ROOM_WORDS = ("room", "rooms", "kitchen", "bathroom", "bedroom", "lounge", "office", "study",
              "hall", "hallway", "corridor", "lobby", "house", "home", "apartment", "flat",
              "studio", "space", "area", "place", "scene", "environment")

#: politeness and filler, dropped before reading (base forms).
FILLER = ("please", "pls", "plz", "kindly", "could you", "can you", "would you",
          "will you", "would you mind", "i would like you to", "i would like to",
          "i want you to", "i need you to", "i want to", "i need to", "let us", "go ahead and",
          "just", "now", "maybe", "perhaps", "try to", "try and", "for me", "thank you",
          "thanks", "ok", "okay", "hey", "hi", "hello", "alright", "well", "a person",
          "the person", "someone", "somebody", "the man", "a man", "the woman", "a woman",
          "you should", "first", "quickly", "slowly", "carefully", "gently", "calmly",
          "casually", "leisurely", "briskly", "quietly", "softly", "lazily", "happily",
          "comfortably", "gracefully", "confidently", "straight", "directly", "right away",
          "immediately", "at once", "if you can", "if possible", "when you can", "really",
          "very", "for a while", "for a bit", "for a moment", "for a second", "briefly")
#: words between a preposition and an object's name ("on the", "onto that big").
DETERMINERS = ("the", "a", "an", "that", "this", "those", "these", "my", "your", "our",
               "his", "her", "their", "its", "one", "big", "small", "large", "little",
               "old", "new", "comfy", "comfortable", "soft", "empty", "free", "other",
               "some", "any", "red", "blue", "green", "white", "black", "brown", "grey",
               "gray", "wooden", "same", "only", "second", "first", "last", "edge", "of",
               "side", "end", "corner", "middle", "front")
#: prepositions that put the body *on* the object named after them ("sit on the desk"),
#: so it is the target even when it is not a seat; other prepositions ("sit at / by the
#: desk") mean the seat nearest it.
DIRECT_PREPOSITIONS = ("on", "onto", "upon", "in", "into", "on top of", "off", "off of",
                       "out of", "from", "atop", "inside")


#: words that end one request and start the next ("walk to the bed, then lie down"); the
#: reader turns sentence punctuation into "|".
CLAUSE_BREAKS = ("|", "then", "after that", "afterwards", "afterward", "finally", "and then",
                 "before that", "once there", "once you be there", "when you get there")
