from baselines.goreloc.vocabulary import COCO_CLASSES, GENERATOR_TO_COCO, N_CLASSES, coco_label
from generators.assets import CATEGORIES
from openreloc_bench.data.scene import STRUCTURAL_CATEGORIES


def test_every_generator_category_has_an_entry_and_every_entry_is_coco_or_none():
    assert N_CLASSES == 80 and len(set(COCO_CLASSES)) == 80
    assert set(CATEGORIES) == set(GENERATOR_TO_COCO)
    assert all(v is None or v in COCO_CLASSES for v in GENERATOR_TO_COCO.values())


def test_labels_of_table_structural_and_foreign_categories():
    assert COCO_CLASSES[coco_label("sofa")] == "couch"
    assert COCO_CLASSES[coco_label("monitor")] == "tv"
    assert coco_label("cabinet") is None  # outside COCO-80: invisible
    assert all(coco_label(c) is None for c in STRUCTURAL_CATEGORIES)
    assert COCO_CLASSES[coco_label("dining_table")] == "dining table"
    assert COCO_CLASSES[coco_label("teddy bear")] == "teddy bear"  # a real dataset's COCO-named category
    assert coco_label("lamp shade") is None and coco_label(None) is None
