"""Shared fixtures: small textures made in code and a small fitted model (no ../shared)."""

import numpy as np
import pytest

from tghop import data
from tghop.synthesis import TGHop

#: Fast settings for tests: the paper's pipeline, fewer clusters and patches.
SMALL = dict(n_channels=(9, 22), gamma=0.01, n_clusters=8, n_codewords=40, stride=4, rng=0)


@pytest.fixture(scope="session")
def bricks96():
    return data.bricks(96, rng=1)


@pytest.fixture(scope="session")
def small_model(bricks96):
    return TGHop(**SMALL).fit(bricks96)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture(scope="module")
def one_torch_thread():
    """Tiny tensors: on a loaded machine, torch's spinning worker threads made tests 40x slower."""
    try:
        import torch
    except ImportError:
        yield
        return
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)
