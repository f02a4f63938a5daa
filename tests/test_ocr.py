"""Reading a text lamp's words back (``lampfab.ocr``, Tesseract): it reads a sharp
phrase (as a block and line by line), and it does not read one blurred past legibility
or a different phrase."""

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from lampfab import ocr, targets

PHRASE = "Sweet dreams little one"
SHAPE = (48, 64)  # a wall at the default profile's 64 px


@pytest.fixture(scope="module")
def wall():
    return targets.text_image(PHRASE, *SHAPE)


def test_tesseract_is_installed():
    # make setup installs it; without it verify cannot say whether a lamp's words read.
    assert ocr.available()


def test_a_sharp_phrase_reads_word_for_word(wall):
    assert ocr.words_read(wall, PHRASE) == 4


@pytest.mark.parametrize("phrase", ["Dream\nbig\nlittle\nstar", "You are\nmy\nsunshine"])
def test_a_short_word_on_a_line_of_its_own_reads(phrase):
    # Read as one block only, Tesseract loses the lone short line of these sharp
    # targets ("big" read as "rh", "my" as "sh"); read line by line it finds them.
    assert ocr.words_read(targets.text_image(phrase, *SHAPE), phrase) == 4


def test_a_phrase_with_photon_noise_and_a_soft_blur_still_reads(wall):
    # What a lamp's LED render looks like: blurred by a quarter of an em and grainy.
    em = targets.text_layout(PHRASE, *SHAPE)[0]
    noisy = np.random.default_rng(0).poisson(gaussian_filter(wall, 0.25 * em / 4) * 200) / 200
    assert ocr.words_read(noisy, PHRASE) == 4


def test_a_phrase_blurred_past_legibility_does_not_read(wall):
    em = targets.text_layout(PHRASE, *SHAPE)[0]
    assert ocr.words_read(gaussian_filter(wall, 0.6 * em / 4), PHRASE) <= 1


def test_a_different_phrase_does_not_read_as_this_one():
    assert ocr.words_read(targets.text_image("Happy birthday", *SHAPE), PHRASE) == 0
    assert ocr.words_read(np.zeros(SHAPE), PHRASE) == 0  # a dark wall


def test_words_ignore_case_and_punctuation_and_count_repeats():
    assert ocr.words("Sweet, DREAMS!  little-one") == ["sweet", "dreams", "little", "one"]
    assert ocr.words("Joyeux anniversaire, Léa — à bientôt") == ["joyeux", "anniversaire", "lea", "a", "bientot"]
    assert ocr.words_read(targets.text_image("one", *SHAPE), "one one") == 1
