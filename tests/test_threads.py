"""Thread counts of a fit (issue #26): one BLAS / OpenMP thread inside TGHop.fit, ICA
clusters on the idle cores, and the model the same bit for bit whatever the counts; one
BLAS thread for the sampling and for ICHM.predict too."""

import os
import sys

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from tghop import _resources, core, data
from tghop.synthesis import TGHop

from conftest import SMALL


def _arrays(model):
    return [model.ichm_.means_, model.ichm_.codebook_, model.sdr_.channel_,
            *[np.asarray(m) for m in model.ichm_.mixing_]]


def test_fit_is_the_same_whatever_the_threads(monkeypatch):
    image = data.bricks(64, rng=2)
    seen = []
    fit_cluster = core.ICHM._fit_cluster

    def spy(self, *args, **kwargs):
        # BLAS only: NumPy uses no OpenMP; an OpenMP runtime in the process (PyTorch's, when
        # other tests loaded it) keeps its count per thread and is not used by the fit.
        seen.append({i["internal_api"]: i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})
        return fit_cluster(self, *args, **kwargs)

    monkeypatch.setattr(core.ICHM, "_fit_cluster", spy)
    monkeypatch.setattr(core, "usable_cores", lambda: 1)
    with threadpool_limits(limits=1):
        one = TGHop(**SMALL).fit(image)
    monkeypatch.setattr(core, "usable_cores", lambda: 4)
    with threadpool_limits(limits=2):
        more = TGHop(**SMALL).fit(image)
        assert {i["num_threads"] for i in threadpool_info()} == {2}  # restored after the fit
    assert seen and all(set(s.values()) == {1} for s in seen)  # one thread inside the fit
    for a, b in zip(_arrays(one), _arrays(more)):
        np.testing.assert_array_equal(a, b)


def test_usable_cores_is_the_affinity_mask(monkeypatch):
    import os

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2, 3}, raising=False)
    assert _resources.usable_cores() == 4
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(), raising=False)
    assert _resources.usable_cores() == 1  # never 0


def test_sampling_holds_one_blas_thread(monkeypatch, small_model):
    # TGHop.sample_patches, sample_vectors and ICHM.sample mix by matrix products: at two BLAS
    # threads they rounded otherwise than at one (synthesize's), so the same seed gave other
    # patches on a machine of another core count (and ICHM.sample other vectors).
    seen = []
    blocks = core.ICHM._blocks

    def spy(self):  # the BLAS threads of the products (mix_by_cluster's loop over the blocks)
        if sys._getframe(1).f_code.co_name == "mix_by_cluster":
            seen.append({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})
        return blocks(self)

    monkeypatch.setattr(core.ICHM, "_blocks", spy)
    with threadpool_limits(limits=2, user_api="blas"):
        patches = small_model.sample_patches(500, rng=3)
        patches32 = small_model.sample_patches(500, rng=3, dtype=np.float32)  # its decoding's products too
        z, _ = small_model.ichm_.sample(500, rng=3)
        assert {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"} <= {2}  # restored after
    assert seen and all(s == {1} for s in seen)
    with threadpool_limits(limits=1, user_api="blas"):
        np.testing.assert_array_equal(small_model.sample_patches(500, rng=3), patches)
        np.testing.assert_array_equal(small_model.sample_patches(500, rng=3, dtype=np.float32), patches32)
        np.testing.assert_array_equal(small_model.ichm_.sample(500, rng=3)[0], z)


def test_predict_holds_one_blas_thread(monkeypatch, small_model):
    # ICHM.predict (transform's and tghop clusters') finds the nearest mean by a matrix product:
    # at two BLAS threads it rounded otherwise than at one, so a vector near a boundary between
    # clusters could get another cluster on a machine of another core count.
    seen = []
    nearest = core.nearest

    def spy(*args, **kwargs):
        seen.append({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})
        return nearest(*args, **kwargs)

    monkeypatch.setattr(core, "nearest", spy)
    z, _ = small_model.ichm_.sample(500, rng=3)
    with threadpool_limits(limits=2, user_api="blas"):
        labels = small_model.ichm_.predict(z, chunk=128)
        transformed, _ = small_model.ichm_.unmix(z)
        assert {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"} <= {2}  # restored after
    assert len(seen) == 2 and all(s == {1} for s in seen)
    np.testing.assert_array_equal(transformed, labels)
    with threadpool_limits(limits=1, user_api="blas"):
        np.testing.assert_array_equal(small_model.ichm_.predict(z), labels)


def test_cluster_map_holds_one_blas_thread(monkeypatch, small_model):
    # tghop clusters: the patches' encoding (the hops' matrix products) as well as predict runs
    # at one BLAS thread, so that a machine of any core count paints the same clusters.
    from tghop import explain

    seen = []
    encode = TGHop.encode

    def spy(self, *args, **kwargs):
        seen.append({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})
        return encode(self, *args, **kwargs)

    monkeypatch.setattr(TGHop, "encode", spy)
    image = data.bricks(64, rng=5)
    with threadpool_limits(limits=2, user_api="blas"):
        labels = explain.cluster_map(small_model, image, stride=4)
        assert {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"} <= {2}  # restored after
    assert seen and all(s == {1} for s in seen)
    with threadpool_limits(limits=1, user_api="blas"):
        np.testing.assert_array_equal(explain.cluster_map(small_model, image, stride=4), labels)


def _blas_threads():
    return {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


def test_overlapping_calls_in_two_threads_hold_one_blas_thread_to_the_last(small_model):
    # A fit in one thread, a synthesis in another, overlapping: each held one BLAS thread with a limit
    # of its own, so the first to finish put the process's count back under the other (which went on,
    # and rounded, on two: a fit in two threads at once gave another model than alone) and the other,
    # finishing, left the process on one BLAS thread for good. 0.57: the holds are counted process-wide.
    import threading

    import threadpoolctl

    limiter = None
    if _blas_threads() == {1}:  # one core: two BLAS threads, so that the process has another count to go back to
        limiter = threadpool_limits(limits=2, user_api="blas")
        clear = getattr(threadpoolctl.OpenBLASController, "clear_controlling_thread", None)  # threadpoolctl >= 3.8
        if clear is not None:
            clear()  # set from this thread, not held by it: the test's threads may change it
    try:
        before = _blas_threads()
        assert before and before != {1}
        fit_in, synth_in, fit_go, synth_go = (threading.Event() for _ in range(4))
        seen, errors = {}, []

        def pause(stage, arrived, go, key):
            def progress(name, done, total):
                if name == stage and not arrived.is_set():
                    arrived.set()
                    assert go.wait(60)
                    seen[key] = _blas_threads()
            return progress

        def run(fn):
            try:
                fn()
            except BaseException as exc:  # noqa: BLE001 (told below)
                errors.append(exc)

        fitting = threading.Thread(target=run, args=(lambda: TGHop(**SMALL).fit(
            data.bricks(64, rng=2), progress=pause("hop 1", fit_in, fit_go, "fit")),))
        making = threading.Thread(target=run, args=(lambda: small_model.synthesize(
            (48, 48), rng=0, progress=pause("quilting", synth_in, synth_go, "synth")),))
        fitting.start()
        assert fit_in.wait(60)
        making.start()
        assert synth_in.wait(60)
        fit_go.set()  # the fit finishes while the synthesis is inside
        fitting.join(60)
        synth_go.set()
        making.join(60)
        assert not errors
        assert seen == {"fit": {1}, "synth": {1}}  # 0.56: the synthesis on the process's count
        assert _blas_threads() == before  # 0.56: one BLAS thread after both
    finally:
        if limiter is not None:
            limiter.restore_original_limits()


@pytest.mark.skipif(not hasattr(os, "fork"), reason="os.fork is not available here")
def test_a_child_forked_while_another_thread_holds_one_blas_thread_is_back_on_the_processs_threads():
    # 0.56 (and 0.57 before register_at_fork): the child inherited the other thread's hold, which no thread of
    # the child would ever end, so it stayed on one BLAS thread for good (and its next hold never set a limit).
    import threading
    import warnings

    import threadpoolctl

    limiter = None
    if _blas_threads() == {1}:  # one core: two BLAS threads, so that the child has another count to go back to
        limiter = threadpool_limits(limits=2, user_api="blas")
        clear = getattr(threadpoolctl.OpenBLASController, "clear_controlling_thread", None)  # threadpoolctl >= 3.8
        if clear is not None:
            clear()
    try:
        before = _blas_threads()
        inside, leave = threading.Event(), threading.Event()

        def hold():
            with _resources.one_blas_thread():
                inside.set()
                leave.wait(60)

        holder = threading.Thread(target=hold)
        holder.start()
        assert inside.wait(60) and _blas_threads() == {1}
        read, write = os.pipe()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # Python 3.12: forking a process with threads
            pid = os.fork()
        if pid == 0:  # the child: report and leave at once
            try:
                told = f"{_resources._BLAS_HOLD['count']} {sorted(_blas_threads())}"
                with _resources.one_blas_thread():
                    told += f" {sorted(_blas_threads())}"
                told += f" {_resources._BLAS_HOLD['count']} {sorted(_blas_threads())}"
            except BaseException as exc:  # noqa: BLE001 (told to the parent)
                told = repr(exc)
            os.write(write, told.encode())
            os._exit(0)
        os.close(write)
        os.waitpid(pid, 0)
        with os.fdopen(read) as pipe:
            told = pipe.read()
        leave.set()
        holder.join(60)
        assert told == f"0 {sorted(before)} [1] 0 {sorted(before)}"
        assert _blas_threads() == before
    finally:
        if limiter is not None:
            limiter.restore_original_limits()


_FIT_IN_A_PROCESS = """
import sys
import numpy as np
from threadpoolctl import threadpool_info
from tghop import data
from tghop.material import Material, example_maps
from tghop.modelfile import save_model
from tghop.synthesis import TGHop

threads = {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}
if threads != {int(sys.argv[2])}:
    print("blas threads", threads)
    sys.exit(3)
settings = dict(n_clusters=6, n_codewords=30, stride=4, rng=0)
albedo = data.bricks(64, rng=3)
save_model(TGHop(**settings).fit(albedo), sys.argv[1] + "-texture.npz")
material = Material(model=TGHop(**settings)).fit(albedo, example_maps(albedo))
save_model(material, sys.argv[1] + "-material.npz")
"""


def test_a_models_files_are_the_same_bytes_fitted_on_one_blas_thread_or_two(tmp_path):
    # A batch worker fits on one BLAS thread, tghop fit and batch --workers 1 on the machine's. 0.59's material
    # fitted its albedo's patch statistics outside the fit's one BLAS thread: patch.quantiles 8e-7 apart, which the
    # patch refinement carried into the albedo's pixels. Each count in a process of its own (OpenBLAS's own
    # setting, as a Dask worker's nanny sets it), every array compared.
    import subprocess

    import tghop

    env = dict(os.environ, PYTHONPATH=os.pathsep.join([os.path.dirname(os.path.dirname(tghop.__file__)),
                                                        os.environ.get("PYTHONPATH", "")]))
    for n in (1, 2):
        env.update({"OPENBLAS_NUM_THREADS": str(n), "OMP_NUM_THREADS": str(n)})
        done = subprocess.run([sys.executable, "-c", _FIT_IN_A_PROCESS, str(tmp_path / f"t{n}"), str(n)], env=env,
                              capture_output=True, text=True, timeout=600)
        if done.returncode == 3:
            pytest.skip(f"OpenBLAS does not run {n} threads here ({done.stdout.strip()})")
        assert done.returncode == 0, done.stderr
    for kind in ("texture", "material"):
        one, two = np.load(tmp_path / f"t1-{kind}.npz"), np.load(tmp_path / f"t2-{kind}.npz")
        assert sorted(one.files) == sorted(two.files)
        assert "material_patch.patch.quantiles" in one.files or kind == "texture"
        for name in one.files:
            assert np.array_equal(one[name], two[name]), (kind, name)
