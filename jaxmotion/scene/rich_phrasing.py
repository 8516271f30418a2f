"""Word lists of the rich instruction phrasing (``sample_task(..., phrasing="rich")``).

Data only; :mod:`jaxmotion.scene.instructions` composes them. A rich instruction is
``<frame>`` around ``<adverb><verb core> <referring expression><suffix>``, or a two-clause
form that still names one action on one object ("find the chair next to the desk and sit
on it"), or, for sitting down and getting up, "<core> the desk" meaning the seat at it.
Every verb core of the default grammar is a core here too; the lists below add to them.

Nothing here is taken from the hand-written description set
(:data:`jaxmotion.eval.descriptions.DESCRIPTIONS`): no verb core occurs in one of its
sentences (tests/test_rich_phrasing.py checks it), so that set stays phrasing the
generator does not write.
"""

from __future__ import annotations

__all__ = ["EXTRA_VERBS", "FRAMES", "IN_ONLY", "MULTI_CLAUSE", "PREFIX_ADVERBS",
           "RELATION_CONNECTORS", "RELATION_WORDS", "RICH_WORDS", "SEAT_AT_ANCHORS",
           "SEAT_AT_VERBS", "SUFFIXES", "SUFFIX_ADVERBS", "SUFFIX_CONDITIONS",
           "SUPERLATIVE_TEMPLATES", "SUPPORTING_TEMPLATES"]

#: verb cores added to :data:`jaxmotion.scene.instructions.VERBS`, per action; each is
#: followed by the referring expression (or "it" in a two-clause form).
EXTRA_VERBS = {
    "walk": ("go up to", "head towards", "head on over to", "move over to", "move towards",
             "make your way over to", "find your way to", "come over to", "come to",
             "step up to", "get over to", "go towards", "proceed to", "hurry over to",
             "hurry to", "jog over to", "walk straight to", "go straight to",
             "walk across the room to", "cross the room to", "go and stand by",
             "go and stand next to", "walk right up to", "take a walk to"),
    "sit": ("sit yourself on", "go and sit on", "go sit down on", "come sit on",
            "come and sit on", "sit down onto", "go take a seat on", "go have a seat on",
            "sit back on", "sit back in", "settle down in", "sit right down on"),
    "stand_up": ("get back up from", "stand up off of", "get up off of", "climb off",
                 "step off", "come up off", "pull yourself up from", "push yourself up from",
                 "lift yourself up off", "get up and leave"),
    "lie": ("lie yourself down on", "lay yourself down on", "have a lie down on",
            "take a rest on", "get some rest on", "stretch out flat on", "go and lie down on",
            "go stretch out on", "take a snooze on", "have a snooze on", "doze off on",
            "go to sleep on", "lay flat on", "lie out on"),
}
#: cores that only fit an armchair ("sit back in the armchair", not "in the stool")
IN_ONLY = ("sit down in", "sit in", "sit back in", "settle down in")
#: "<core> the desk": the seat at the desk (the seat nearest it, as the reader takes it)
SEAT_AT_VERBS = {"sit": ("take a seat at", "have a seat at", "sit yourself down at",
                         "go have a seat at", "go take a seat at"),
                 "stand_up": ("get up from", "stand up from", "rise from", "get back up from")}
#: classes one sits at
SEAT_AT_ANCHORS = ("desk", "table", "coffee table")
#: adverbs before the core ("" for none)
PREFIX_ADVERBS = ("", "", "", "slowly ", "carefully ", "quickly ", "calmly ", "gently ",
                  "casually ", "quietly ")
#: endings after the referring expression, per action ("" for none): adverbs, durations,
#: purpose clauses that name no other action or object
SUFFIXES = {
    "walk": ("", "", " slowly", " quickly", " carefully", " right away", " and wait there",
             " and stop there", " if you can"),
    "sit": ("", "", " for a moment", " for a while", " for a second", " to rest your legs",
            " slowly", " carefully", " if you can"),
    "stand_up": ("", "", " slowly", " carefully", " right away", " if you can",
                 " when you can"),
    "lie": ("", "", " for a while", " for a moment", " to take a nap", " to get some rest",
            " slowly", " carefully"),
}
#: suffixes that are adverbs (not after an adverb before the core: "slowly ... quickly")
SUFFIX_ADVERBS = (" slowly", " quickly", " carefully")
#: suffixes that are conditions or urgency: only in a frame that ends with the verb phrase
#: and does not start with a condition ("when you're ready, ... right away")
SUFFIX_CONDITIONS = (" if you can", " when you can", " right away")
#: frames around "<adverb><core> <expression><suffix>" ({v}); a frame ending in "?" asks
FRAMES = ("{v}", "{v}", "{v}", "please {v}", "{v}, please", "please, {v}", "now {v}",
          "now, {v}", "just {v}", "go ahead and {v}", "kindly {v}", "could you {v}?",
          "could you please {v}?", "can you {v}?", "can you please {v}?", "would you {v}?",
          "would you please {v}?", "will you {v}?", "i'd like you to {v}",
          "i would like you to {v}", "i want you to {v}", "i need you to {v}",
          "why don't you {v}?", "ok, {v}", "okay, {v}", "alright, {v}", "hey, {v}",
          "{v} for me", "{v} for me, please", "{v}, thanks", "{v}, thank you",
          "if you don't mind, {v}", "when you're ready, {v}", "it's time to {v}",
          "try to {v}", "you should {v}")
#: two-clause forms naming one action on one object: {e} the referring expression, {E} it
#: at the start of the sentence, {c} the verb core (followed by "it")
MULTI_CLAUSE = {
    "walk": ("find {e} and {c} it", "{E}: {c} it", "see {e}? {c} it",
             "look for {e}, then {c} it"),
    "sit": ("go over to {e} and {c} it", "find {e} and {c} it", "{E}: {c} it",
            "see {e}? {c} it", "walk up to {e}, then {c} it", "look for {e}, then {c} it"),
    "stand_up": ("you're on {e}; {c} it", "you are sitting on {e}. {c} it",
                 "{E}: {c} it"),
    "lie": ("go over to {e} and {c} it", "find {e} and {c} it", "{E}: {c} it",
            "walk up to {e}, then {c} it"),
}
#: object words (class -> words) of the rich space; the default's
#: :data:`jaxmotion.scene.instructions.WORDS` are among them
RICH_WORDS = {
    "sofa": ("sofa", "couch", "settee", "loveseat"),
    "armchair": ("armchair", "easy chair", "recliner", "lounge chair"),
    "stool": ("stool", "bar stool", "barstool"),
    "table": ("table", "dining table", "kitchen table"),
    "coffee table": ("coffee table", "low table"),
    "desk": ("desk", "writing desk", "work desk"),
    "nightstand": ("nightstand", "bedside table", "night table", "bedside cabinet"),
    "cabinet": ("cabinet", "cupboard"),
    "bookshelf": ("bookshelf", "bookcase", "book shelf"),
    "door": ("door", "doorway"),
    "picture": ("picture", "painting", "artwork", "framed picture"),
    "sink": ("sink", "washbasin", "wash basin"),
    "fridge": ("fridge", "refrigerator"),
    "tv": ("tv", "television", "tv set"),
    "toilet": ("toilet", "loo"),
}
#: words between the target and its relation ("the chair that is next to the desk")
RELATION_CONNECTORS = ("", "that is ", "which is ", "that's ", "located ", "placed ",
                       "positioned ", "situated ")
#: relation words per pool (``near``: ``closest`` within a metre), each followed by the
#: anchor(s); a word given as ``(word, True)`` takes only the first four connectors (it is
#: a participle itself: "standing on")
RELATION_WORDS = {
    "closest": ("closest to", "nearest to", "nearest", "closest to", "nearest to"),
    "near": ("next to", "right next to", "right by", "close to", "beside", "by", "near",
             "alongside", "just next to", "just by", "close by"),
    "farthest": ("farthest from", "furthest from", "farthest away from",
                 "furthest away from", "most distant from"),
    "between": ("between", "in between", "halfway between", "midway between"),
    "on": ("on", "on top of", "atop", ("resting on", True), ("standing on", True),
           ("sitting on", True)),
    "above": ("above", "over", "up above", ("hanging above", True), ("hanging over", True),
              ("mounted above", True)),
    "below": ("below", "beneath", "underneath", "under"),
}
#: "supporting" phrasings (the target holds the anchor), {a} the anchor
SUPPORTING_TEMPLATES = ("with the {a} on it", "with the {a} on top", "that has the {a} on it",
                        "which has the {a} on it", "that the {a} is on",
                        "which the {a} is on", "supporting the {a}", "that supports the {a}",
                        "holding the {a}", "that holds the {a}", "carrying the {a}",
                        "that carries the {a}")
#: the superlative before the class ("the nearest chair to the desk"), per pool
SUPERLATIVE_TEMPLATES = {
    "closest": ("the nearest {t} to the {a}", "the closest {t} to the {a}"),
    "farthest": ("the farthest {t} from the {a}", "the furthest {t} from the {a}"),
}
