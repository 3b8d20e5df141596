"""The nearest explanations (service/diagnosis/nearest.py): when nothing fits, ranked by their share."""

import numpy as np
from test_compose import Counted, small

from service.diagnosis.combination import merged
from service.diagnosis.nearest import nearest
from service.diagnosis.records import Term
from tracer import Renderer


def test_nearest_explanations_are_ranked_by_their_share_of_the_difference():
    scene = small("01_three_spheres")
    reference = Renderer(scene).pixels()
    submitted = np.clip(Renderer(scene, merged(("no-shadows",))).pixels().astype(int) + 9, 0, 255).astype(np.uint8)
    ranked = nearest(reference, submitted, Counted(scene).looks(), [(Term("ambient", None, 3.0), 0.2)])
    assert ranked and ranked[0].variant == "no-shadows"
    assert [e.share for e in ranked] == sorted((e.share for e in ranked), reverse=True)
    assert any(e.term is not None and e.term.name == "ambient" for e in ranked)
