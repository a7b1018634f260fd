"""GOReloc's closed vocabulary: the 80 COCO classes of its YOLOv8 detector, and the committed table
from every category of the project's generator to one of them (or to none).

GOReloc sees only what a COCO detector reports, so an object whose category has no COCO class is
invisible to it (as the paper under study argues it is in real scenes). The table says, per
generator category, what a COCO-trained detector would call it; the choices follow COCO's own
annotation habits (COCO annotates every table as "dining table", monitors as "tv", stools and
armchairs as "chair").
"""

from __future__ import annotations

from openreloc_bench.data.scene import STRUCTURAL_CATEGORIES

COCO_CLASSES: tuple[str, ...] = (
    "person", "bicycle", "car", "motorcycle", "airplane", "bus", "train", "truck", "boat",
    "traffic light", "fire hydrant", "stop sign", "parking meter", "bench", "bird", "cat", "dog",
    "horse", "sheep", "cow", "elephant", "bear", "zebra", "giraffe", "backpack", "umbrella",
    "handbag", "tie", "suitcase", "frisbee", "skis", "snowboard", "sports ball", "kite",
    "baseball bat", "baseball glove", "skateboard", "surfboard", "tennis racket", "bottle",
    "wine glass", "cup", "fork", "knife", "spoon", "bowl", "banana", "apple", "sandwich", "orange",
    "broccoli", "carrot", "hot dog", "pizza", "donut", "cake", "chair", "couch", "potted plant",
    "bed", "dining table", "toilet", "tv", "laptop", "mouse", "remote", "keyboard", "cell phone",
    "microwave", "oven", "toaster", "sink", "refrigerator", "book", "clock", "vase", "scissors",
    "teddy bear", "hair drier", "toothbrush",
)  # fmt: skip
"""The 80 COCO detection classes in the order of their YOLO label ids (label = index)."""

N_CLASSES = len(COCO_CLASSES)

GENERATOR_TO_COCO: dict[str, str | None] = {
    "armchair": "chair",
    "basketball": "sports ball",
    "bathtub": None,
    "bed": "bed",
    "bench": "bench",
    "bicycle": "bicycle",
    "binder": None,
    "book_stack": "book",
    "bookshelf": None,
    "bottle": "bottle",
    "bowl": "bowl",
    "cabinet": None,
    "cactus": "potted plant",  # the generator's cactus stands in a pot
    "candle": None,
    "ceiling_light": None,
    "clock": "clock",
    "coat_rack": None,
    "coffee_maker": None,
    "coffee_table": "dining table",
    "cushion": None,
    "desk": "dining table",
    "desk_lamp": None,
    "desk_organiser": None,
    "dining_chair": "chair",
    "dining_table": "dining table",
    "dresser": None,
    "drum": None,
    "dumbbell": None,
    "fan": None,
    "filing_cabinet": None,
    "fire_extinguisher": None,
    "floor_lamp": None,
    "fridge": "refrigerator",
    "fruit_bowl": "bowl",
    "globe": None,
    "guitar": None,
    "kettle": None,
    "keyboard": "keyboard",
    "laptop": "laptop",
    "laundry_basket": None,
    "microwave": "microwave",
    "mirror": None,
    "monitor": "tv",
    "mug": "cup",
    "nightstand": None,
    "office_chair": "chair",
    "oven": "oven",
    "painting": None,
    "pan": None,
    "piano": None,
    "picture_frame": None,
    "plate_stack": None,
    "pot": None,
    "potted_plant": "potted plant",
    "printer": None,
    "radio": None,
    "rug": None,
    "sculpture": None,
    "shoe_rack": None,
    "side_table": "dining table",
    "sink": "sink",
    "soap_bottle": "bottle",
    "sofa": "couch",
    "speaker": None,
    "stool": "chair",
    "suitcase": "suitcase",
    "table_lamp": None,
    "tall_plant": "potted plant",
    "teapot": None,
    "teddy_bear": "teddy bear",
    "toaster": "toaster",
    "toilet": "toilet",
    "toilet_paper": None,
    "toothbrush_cup": "cup",
    "towel_rack": None,
    "toy_ball": "sports ball",
    "toy_blocks": None,
    "toy_car": "car",  # COCO detectors fire on toy cars
    "trash_can": None,
    "tv": "tv",
    "tv_stand": None,
    "vase": "vase",
    "wardrobe": None,
    "washing_machine": None,
    "whiteboard": None,
    "wine_glass": "wine glass",
    "yoga_mat": None,
}
"""Generator category -> the COCO class a COCO detector would report for it, or None (invisible)."""


def coco_label(category: str | None) -> int | None:
    """COCO label id of a dataset category, or None when GOReloc's detector cannot see it.

    Generator categories use the table; structural ones (walls, floors...) are never detected; any
    other category (e.g. of a converted real dataset) is visible only when it is itself a COCO class
    name ('dining_table' and 'dining table' both are).
    """
    if category is None or category in STRUCTURAL_CATEGORIES:
        return None
    name = GENERATOR_TO_COCO[category] if category in GENERATOR_TO_COCO else category.replace("_", " ")
    return COCO_CLASSES.index(name) if name in COCO_CLASSES else None


def background_nouns() -> list[str]:
    """Nouns of what a COCO detector must not report: the structural parts and every generator
    category without a COCO class (the negatives of the predicted track's zero-shot labelling)."""
    structural = ["wall", "floor", "ceiling", "door", "window", "stairs"]
    return structural + sorted(c.replace("_", " ") for c, name in GENERATOR_TO_COCO.items() if name is None)
