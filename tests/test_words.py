"""Words for a student (service/words.py): names in quotes or places, numbers in plain words."""

import pytest
from test_names import SCENE

import schemas
from service.diagnosis.words import Names, how_bright, lights_line, names_of, objects_line, share_words, term_sentence


@pytest.fixture(scope="module")
def names() -> Names:
    return names_of(schemas.validate_scene(SCENE))


@pytest.mark.parametrize(
    "scale, words",
    [
        (0.0, "missing"),
        (0.04, "missing"),
        (2.0, "twice as bright"),
        (1.95, "twice as bright"),
        (0.5, "half as bright"),
        (0.26, "a quarter as bright"),
        (3.1, "three times as bright"),
        (1.3, "about 1.3 times as bright"),
        (0.85, "about 0.8 times as bright"),
    ],
)
def test_a_scale_in_plain_words(scale, words):
    assert how_bright(scale) == words


def test_terms_name_their_light_by_name_or_place(names):
    assert term_sentence("specular", 1, 0.0, names) == "the specular of light 'key' is missing"
    assert term_sentence("diffuse", 2, 2.0, names) == (
        "the diffuse of the third light (area) is twice as bright as the reference's"
    )
    assert term_sentence("reflection", None, 0.5, names) == "the reflections are half as bright as the reference's"
    assert term_sentence("ambient", None, 0.0, names) == "the ambient term is missing"


def test_objects_and_lights_in_words(names):
    assert objects_line([(2, 0.5851), (-1, 0.2)], names) == "sphere 'glass ball' 59 %, the background 20 %"
    assert objects_line([(1, 0.1)], names) == "the first sphere 10 %"
    assert lights_line([(2, 0.85)], names) == "the third light (area) 85 %"
    assert Names((), ()).light(3) == "lights[3]"


@pytest.mark.parametrize(
    "share, words", [(0.9, "most of"), (0.4, "about half of"), (0.2, "some of"), (0.01, "a little of")]
)
def test_shares_in_words(share, words):
    assert share_words(share) == words


def test_mistakes_together_and_the_nearest_in_a_sentence():
    from service.diagnosis.words import nearest_sentence, together_sentence

    assert together_sentence(["no shadow rays", "gamma"], 0.0, True).startswith(
        "Likely two mistakes together: no shadow rays and gamma — the submission matches the reference rendered "
        "with both"
    )
    assert "a, b, and c" in together_sentence(["a", "b", "c"], 0.01, False)
    assert "comes closest" in together_sentence(["a", "b", "c"], 0.01, False)
    assert nearest_sentence("the specular of light 'key'", 0.62) == (
        "No known mistake fits exactly: most of the difference is the specular of light 'key' (about 62 %)"
    )
