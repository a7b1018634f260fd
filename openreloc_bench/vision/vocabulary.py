"""Words for the offline encoder's training captions and the offline describer's open vocabulary.

Two lists matter for honesty: :data:`HELD_OUT_SYNONYMS` are words the training captions never use
(enforced when captions are built), so text-to-image retrieval with them measures how much of the
frozen text tower's language knowledge carries over; and :data:`OBJECT_NOUNS` reaches far beyond the
generator's categories, so the describer is not a closed classifier in disguise.
"""

from __future__ import annotations

import re

COLOURS: tuple[str, ...] = (
    "red",
    "dark red",
    "maroon",
    "orange",
    "yellow",
    "gold",
    "green",
    "dark green",
    "olive",
    "lime green",
    "teal",
    "turquoise",
    "light blue",
    "blue",
    "navy",
    "purple",
    "lavender",
    "pink",
    "magenta",
    "white",
    "cream",
    "beige",
    "tan",
    "light brown",
    "brown",
    "dark brown",
    "grey",
    "light grey",
    "dark grey",
    "silver",
    "black",
    "copper",
)
"""Colour names the describer can choose from (a superset of the generator's)."""

MATERIALS: tuple[str, ...] = (
    "wooden",
    "fabric",
    "metal",
    "ceramic",
    "glass",
    "leather",
    "plastic",
    "stone",
    "paper",
    "rubber",
    "wicker",
    "marble",
    "velvet",
    "steel",
    "porcelain",
    "concrete",
    "bamboo",
    "cardboard",
)
"""Material adjectives for describer phrases."""

MATERIAL_ADJECTIVE = {"wood": "wooden", "foliage": "leafy"}
"""Generator material keys whose adjective differs from the noun."""

_NOUNS = """
armchair, bed, sofa, couch, loveseat, chaise longue, ottoman, footstool, pouf, beanbag, chair, stool, bar stool,
bench, rocking chair, dining chair, office chair, desk chair, high chair, folding chair, recliner, futon, daybed,
bunk bed, crib, hammock, table, dining table, coffee table, side table, end table, console table, desk,
writing desk, computer desk, nightstand, bedside table, dresser, chest of drawers, wardrobe, closet, armoire,
cabinet, cupboard, sideboard, buffet, hutch, credenza, bookshelf, bookcase, shelf, wall shelf, shelving unit,
tv stand, media console, shoe rack, coat rack, hat stand, umbrella stand, room divider, filing cabinet,
vanity, mirror, full-length mirror, headboard, lamp, floor lamp, table lamp, desk lamp, ceiling lamp,
pendant light, chandelier, wall sconce, lantern, candle, candlestick, light bulb, television, tv, monitor,
computer, laptop, keyboard, computer mouse, printer, scanner, speaker, radio, stereo, record player,
headphones, game console, remote control, router, telephone, smartphone, tablet, clock, wall clock,
alarm clock, projector, camera, fan, ceiling fan, heater, radiator, air conditioner, air purifier,
humidifier, vacuum cleaner, iron, ironing board, fridge, refrigerator, freezer, oven, stove, cooktop,
microwave, dishwasher, washing machine, washer, dryer, kettle, toaster, coffee maker, coffee machine,
espresso machine, blender, mixer, food processor, rice cooker, slow cooker, range hood, sink, faucet,
kitchen island, counter, mug, cup, teacup, glass, wine glass, tumbler, bowl, fruit bowl, salad bowl, plate,
stack of plates, dish, saucer, tray, bottle, wine bottle, water bottle, jar, jug, pitcher, carafe, vase,
teapot, pot, saucepan, pan, frying pan, wok, cutting board, knife block, dish rack, spice rack, bread box,
canister, tin can, lunch box, thermos, fruit, apple, orange, banana, lemon, loaf of bread, cake,
potted plant, plant, houseplant, flower pot, planter, cactus, succulent, bonsai tree, fern, flowers, bouquet,
book, stack of books, notebook, magazine, newspaper, folder, binder, envelope, calendar, picture frame,
photo frame, painting, poster, artwork, canvas, map, sculpture, statue, figurine, trophy, globe, pillow,
cushion, throw pillow, blanket, quilt, duvet, rug, carpet, doormat, mat, curtain, blind, towel, basket,
laundry basket, trash can, waste bin, recycling bin, bucket, storage box, box, cardboard box, crate, suitcase,
backpack, handbag, bag, briefcase, shopping bag, toilet, bathtub, shower, bathroom sink, toilet paper,
soap dispenser, toothbrush holder, bath mat, bathroom scale, hair dryer, guitar, piano, violin, drum, toy,
teddy bear, doll, ball, toy car, board game, puzzle, bicycle, skateboard, helmet, dumbbell, yoga mat,
treadmill, shoe, boot, pair of shoes, slippers, hat, coat, jacket, dress, shirt, whiteboard, blackboard,
bulletin board, easel, aquarium, fish tank, birdcage, pet bed, fire extinguisher, smoke detector,
first aid kit, toolbox, ladder, step stool, water dispenser, wine rack, bar cart, trolley, door, window,
wall, floor, ceiling, stairs, railing, column, baseboard, light switch, power outlet, thermostat, pipe,
vent, shower curtain, bath towel, hand towel, soap, sponge, detergent bottle, spray bottle, watering can,
broom, mop, dustpan, extension cord, charger, cable, lamp shade, coaster, napkin, tablecloth, placemat,
salt shaker, pepper grinder, oil bottle, sugar bowl, cookie jar, ice bucket, cocktail shaker, decanter,
kitchen scale, timer, grater, colander, ladle, spatula, whisk, rolling pin, baking tray, casserole dish,
dutch oven, pressure cooker, steamer, griddle, waffle maker, juicer, egg cooker, milk frother, water filter,
bread maker, ice cream maker, deep fryer, air fryer, grill, barbecue, bookend, desk organizer, pen holder,
pencil cup, stapler, tape dispenser, paper tray, letter box, mailbox, key holder, wall hook, hanger,
jewelry box, music box, photo album, scrapbook, piggy bank, snow globe, hourglass, metronome, typewriter,
sewing machine, spinning wheel, loom, telescope, microscope, binoculars, magnifying glass, compass,
barometer, thermometer, weather station, ceiling light, desk organiser, tall plant, toy blocks, book stack,
soap bottle, toothbrush cup, towel rack, toy ball, basketball, plate stack
"""
OBJECT_NOUNS: tuple[str, ...] = tuple(
    dict.fromkeys(n.strip() for n in _NOUNS.replace("\n", " ").split(",") if n.strip())
)
"""Several hundred indoor object nouns: the describer's open noun vocabulary."""

HELD_OUT_SYNONYMS: dict[str, tuple[str, ...]] = {
    "sofa": ("couch", "settee"),
    "bookshelf": ("bookcase",),
    "wardrobe": ("closet", "armoire"),
    "fridge": ("refrigerator",),
    "nightstand": ("bedside table",),
    "office_chair": ("desk chair",),
    "mug": ("coffee cup",),
    "washing_machine": ("washer",),
    "coffee_maker": ("coffee machine",),
    "floor_lamp": ("standing light",),
    "potted_plant": ("houseplant",),
    "tv": ("television",),
    "trash_can": ("waste bin", "garbage bin"),
    "rug": ("carpet",),
    "cushion": ("throw pillow",),
    "pot": ("saucepan",),
    "dresser": ("chest of drawers",),
    "cabinet": ("cupboard",),
    "picture_frame": ("photo frame",),
    "painting": ("artwork",),
    "speaker": ("loudspeaker",),
    "monitor": ("computer screen",),
    "bicycle": ("bike",),
    "sink": ("washbasin",),
}
"""Category -> synonyms that training captions never contain (evaluation only)."""

CAPTION_TEMPLATES: tuple[str, ...] = (
    "a photo of a {noun}",
    "a {noun}",
    "the {noun}",
    "a {colour} {noun}",
    "a {mat} {noun}",
    "a {colour} {mat} {noun}",
    "a {noun} made of {matn}",
    "a {noun} in {colour}",
    "a photo of the {colour} {noun}",
    "there is a {colour} {noun} in the room",
    "a picture of a {mat} {noun} in {colour}",
)
"""Paraphrase templates for training captions (colour and material names from objects.json)."""

ZERO_SHOT_TEMPLATE = "a photo of a {noun}"
"""The prompt for zero-shot classification (and for the describer's noun choice)."""


def noun(category: str) -> str:
    """Category key -> natural noun ('dining_table' -> 'dining table')."""
    return category.replace("_", " ").strip()


def an(phrase: str) -> str:
    """'a' or 'an' before ``phrase`` (by its first letter; good enough for these words)."""
    return "an" if phrase[:1].lower() in "aeiou" else "a"


def with_article(phrase: str) -> str:
    """Fix 'a' -> 'an' at the start of a templated phrase ('a orange chair' -> 'an orange chair')."""
    return re.sub(r"\ba ([aeiouAEIOU])", r"an \1", phrase)


def held_out_words(categories: set[str] | None = None) -> set[str]:
    """Every held-out synonym, lower case, minus any that is itself one of ``categories``' nouns."""
    taken = {noun(c).lower() for c in categories or ()}
    return {s.lower() for syns in HELD_OUT_SYNONYMS.values() for s in syns} - taken


def contains_held_out(text: str, words: set[str] | None = None) -> bool:
    t = f" {re.sub(r'[^a-z ]+', ' ', text.lower())} "
    return any(f" {w} " in t for w in (words if words is not None else held_out_words()))
