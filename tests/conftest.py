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


def assert_user_error(r, *fragments):
    """Non-zero exit, one 'Error:' line naming the problem, no traceback."""
    err = r.stderr.decode()
    assert r.returncode != 0
    assert "Traceback" not in err
    lines = [line for line in err.strip().splitlines() if line.startswith("Error")]
    assert len(lines) == 1, err
    for fragment in fragments:
        assert fragment in lines[0], err
