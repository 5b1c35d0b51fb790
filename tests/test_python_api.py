"""The library as a Python user in a script or a notebook meets it (0.58): what a slip of theirs is told."""

import pathlib

import numpy as np
import pytest

import tghop
from tghop import metrics
from tghop.inpaint import extend, inpaint
from tghop.material import Material


@pytest.mark.parametrize("call, name", [
    (lambda m, b, hole: tghop.TGHop().fit("texture.png"), "exemplar"),
    (lambda m, b, hole: tghop.TGHop().fit(pathlib.Path("texture.png")), "exemplar"),
    (lambda m, b, hole: inpaint(m, "texture.png", hole), "the image"),
    (lambda m, b, hole: inpaint(m, b, "texture.png"), "the mask"),
    (lambda m, b, hole: extend(m, "texture.png", (96, 160)), "the image"),
    (lambda m, b, hole: tghop.synthesize_guided([m, m], "texture.png"), "the guide"),
    (lambda m, b, hole: metrics.sliced_wasserstein(b, "texture.png"), "result"),
    (lambda m, b, hole: Material().fit(b, {"height": "texture.png"}), "map 'height'"),
])
def test_a_file_name_where_an_image_belongs_is_told_to_read_it_first(call, name, small_model, bricks96):
    # NumPy reads a name as a 0-d array of text: 0.57 said "must have shape (H, W) ..., got ()" or
    # "the mask must be numbers or booleans, got dtype <U11".
    hole = np.zeros(bricks96.shape[:2], dtype=bool)
    hole[30:60, 30:60] = True
    with pytest.raises(tghop.InvalidImageError) as caught:
        call(small_model, bricks96, hole)
    assert str(caught.value) == (f"{name} is a file name ('texture.png'), not an image array; read it first: "
                                 "tghop.imageio.load_image(path)")
