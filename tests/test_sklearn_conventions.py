"""scikit-learn's estimator checks on the components that follow its conventions (Saab), and the
one-line messages that keep tghop's wording beside the phrases those checks look for.

Hop, HopStack and SpatialReduction take (n, H, W, C) arrays, which their tags say, so that
scikit-learn's checks (which feed 2-D arrays) skip them; ICHM's ``transform`` returns
``(labels, sources)``, not a transformer's array, and it is not checked.
"""

import warnings

import numpy as np
import pytest

from tghop._errors import NonNumericError, TGHopError
from tghop.hops import Hop, HopStack
from tghop.material import Material
from tghop.saab import Saab
from tghop.sdr import SpatialReduction
from tghop.synthesis import TGHop

sklearn = pytest.importorskip("sklearn")
if tuple(int(v) for v in sklearn.__version__.split(".")[:2]) < (1, 6):
    pytest.skip("scikit-learn before 1.6 has no __sklearn_tags__", allow_module_level=True)

import sklearn.base  # noqa: E402
from sklearn.exceptions import SkipTestWarning  # noqa: E402
from sklearn.utils.estimator_checks import check_estimator, parametrize_with_checks  # noqa: E402


with warnings.catch_warnings():  # tghop's own BaseEstimator, by design: no scikit-learn import to generate
    warnings.filterwarnings("ignore", "Estimator Saab does not inherit from `sklearn.base.BaseEstimator`")
    saab_checks = parametrize_with_checks([Saab(), Saab(n_components="knee")])


@saab_checks
def test_saab_passes_scikit_learn_estimator_checks(estimator, check):
    check(estimator)


@pytest.mark.parametrize("call, words", [
    (lambda s: Saab().fit(np.zeros((1, 10))),
     r"^Saab needs at least 2 vectors: found 1 sample\(s\) \(shape=\(1, 10\)\) while a minimum of 2 is required; "
     r"give X at least 2 rows$"),
    (lambda s: Saab().fit(np.zeros((12, 0))),
     r"^Saab needs vectors of dimension d >= 2: found 0 feature\(s\) \(shape=\(12, 0\)\) while a minimum of 2 is "
     r"required; give X of shape \(n_samples, d\) with d >= 2$"),
    (lambda s: s.transform(np.zeros(4)),
     r"^X must have shape \(n, d\) = \(n, 4\), got \(4,\)\. Reshape your data: X\.reshape\(1, -1\) if it is one "
     r"sample"),
    (lambda s: s.transform(np.zeros((3, 1))),
     r"^X must have shape \(n, d\) = \(n, 4\) for this fitted model, got \(3, 1\); X has 1 features, but Saab is "
     r"expecting 4 features as input$"),
    (lambda s: Saab().fit(np.ones((3, 4)) + 1j),
     r"^X holds complex numbers; give real ones, of shape \(n_samples, d\) \(Complex data not supported\)$"),
    (lambda s: Saab().fit([["a"] * 4] * 3),
     r"^X must be an array of numbers of shape \(n_samples, d\), got list \(could not convert string to float: 'a'\)$"),
], ids=["1 sample", "0 features", "1-D", "width", "complex", "string"])
def test_saab_messages_name_the_problem_and_the_fix_in_one_line(call, words):
    fitted = Saab().fit(np.random.default_rng(0).normal(size=(20, 4)))
    with pytest.raises(TGHopError, match=words) as caught:
        call(fitted)
    assert "\n" not in str(caught.value)


def test_a_non_number_in_an_array_is_a_type_error_too():
    # NumPy's own error for it is a TypeError, and scikit-learn's checks expect one.
    X = np.ones((3, 4), dtype=object)
    X[0, 0] = {"foo": "bar"}
    with pytest.raises(NonNumericError, match=r"^X must be an array of numbers .* got ndarray of dtype object "
                                              r"\(float\(\) argument must be a string or a real number, not 'dict'\)"):
        Saab().fit(X)
    assert issubclass(NonNumericError, TypeError) and issubclass(NonNumericError, TGHopError)


@pytest.mark.parametrize("estimator", [Hop(), HopStack(), SpatialReduction()], ids=lambda e: type(e).__name__)
def test_four_d_components_tell_scikit_learn_its_checks_do_not_apply(estimator):
    with pytest.warns(SkipTestWarning, match="Can't test estimator"):
        results = check_estimator(estimator, on_fail=None)
    assert [r["status"] for r in results if r["status"] != "passed"] == []
    assert not estimator.__sklearn_tags__().input_tags.two_d_array


def test_rng_refuses_a_bool_as_every_integer_parameter_does(small_model):
    # True was taken as the seed 1 at fit, but a model file records no seed for it (settings.recorded_seed).
    from tghop._common import check_rng

    for call in (lambda: check_rng(True), lambda: small_model.sample_patches(2, rng=False),
                 lambda: TGHop(rng=True).fit(np.zeros((40, 40, 3)))):
        with pytest.raises(TGHopError, match=r"^rng must be None, an int seed or numpy.random.Generator, got bool$"):
            call()
    assert check_rng(np.int64(3)).integers(100) == np.random.default_rng(3).integers(100)


def test_set_params_of_a_nested_parameter_of_no_estimator_is_a_one_line_error():
    # Material().set_params(model__rng=1) with model None was Python's AttributeError on None.
    with pytest.raises(TGHopError, match=r"^invalid parameter 'model__rng' for Material: its model is None, "
                                         r"not an estimator; set model first"):
        Material().set_params(model__rng=1)
    mat = Material().set_params(model=TGHop(), model__rng=4)
    assert mat.model.rng == 4 and sklearn.base.clone(mat).get_params()["model__rng"] == 4
