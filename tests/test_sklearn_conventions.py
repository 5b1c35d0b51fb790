"""scikit-learn's estimator checks on every learned component, and the one-line messages that keep tghop's wording
beside the phrases those checks look for.

Which checks run on which component (0.61):

* ``Saab`` and ``ICHM`` take 2-D arrays (n_samples, n_features): ``check_estimator`` runs whole on them and passes
  (ICHM's only skip, ``check_array_api_input``, is scikit-learn's own without ``SCIPY_ARRAY_API``). 0.60's
  ``ICHM.transform`` returned ``(labels, sources)``, and ``check_estimator`` stopped at "ICHM seems to be a
  Transformer"; that pair is ``unmix``'s now and ``transform`` gives one array (its 26 checks were run one by one).
* ``Hop``, ``HopStack`` and ``SpatialReduction`` take (n, H, W, C) arrays, and ``TGHop``, ``CoarseLayout``,
  ``Material``, ``BandStatistics``, ``ColourClasses``, ``PatchStatistics`` and ``CoocGAN`` one (H, W, C) image: their
  tags say so, and ``check_estimator`` skips them, since every check that fits builds a 2-D ``X`` (a patch or image
  model has no meaning for 20 rows of 3 numbers). The checks that feed no data (:data:`NO_DATA_CHECKS`) are run on
  each of them below and pass; what the skipped ones would hold (a constructor that stores its parameters, clone and
  set_params, learned state ending in ``_``, NotFittedError from every public method before fit, ``fit(X, y=None)``)
  is held by this file's own tests over all of them.
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

from conftest import SMALL

sklearn = pytest.importorskip("sklearn")
if tuple(int(v) for v in sklearn.__version__.split(".")[:2]) < (1, 6):
    pytest.skip("scikit-learn before 1.6 has no __sklearn_tags__", allow_module_level=True)

import sklearn.base  # noqa: E402
from sklearn.exceptions import SkipTestWarning  # noqa: E402
from sklearn.utils.estimator_checks import check_estimator, parametrize_with_checks  # noqa: E402


def _ichm():
    from tghop.core import ICHM

    return ICHM(n_clusters=2, min_cluster_size=2, rng=0)  # the checks' 20 to 30 rows: 2 clusters of at least 2


with warnings.catch_warnings():  # tghop's own BaseEstimator, by design: no scikit-learn import to generate
    warnings.filterwarnings("ignore", "Estimator (Saab|ICHM) does not inherit from `sklearn.base.BaseEstimator`")
    saab_checks = parametrize_with_checks([Saab(), Saab(n_components="knee")])
    ichm_checks = parametrize_with_checks([_ichm()])


@saab_checks
def test_saab_passes_scikit_learn_estimator_checks(estimator, check):
    check(estimator)


@ichm_checks
def test_ichm_passes_scikit_learn_estimator_checks(estimator, check):
    # 0.60: check_estimator(ICHM()) stopped before any check ("ICHM seems to be a Transformer, but the
    # `transformer_tags` tag is not set"): its transform returned (labels, sources). Since 0.61 it returns one array;
    # the checks it then met: check_transformer_n_iter (no n_iter_), check_dict_unchanged (transform made the float64
    # mixing matrix's cache), check_n_features_in_after_fitting, check_fit2d_1sample and
    # check_estimators_empty_data_messages (scikit-learn's words missing from tghop's messages).
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "Estimator ICHM does not inherit from `sklearn.base.BaseEstimator`")
        check(estimator)


def test_check_estimator_runs_whole_on_ichm():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        results = check_estimator(_ichm(), on_fail=None)
    left = {r["check_name"] for r in results if r["status"] != "passed"}
    assert left <= {"check_array_api_input"} and len(results) > 40, left  # that one: scikit-learn's, no SCIPY_ARRAY_API


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
    from tghop._estimator import check_rng

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


# ------------------------------------------------------------------ every learned component
# The conventions the components of images and 4-D arrays keep (scikit-learn's check_estimator skips them: every check
# that fits builds 2-D arrays), each over all the components, so that a new component or method is held to them too.

def _components():
    from tghop.colour import ColourClasses
    from tghop.cooc.model import CoocGAN  # importing it needs no PyTorch; none of these tests trains it
    from tghop.core import ICHM
    from tghop.patch_refine import PatchStatistics
    from tghop.refine import BandStatistics
    from tghop.synthesis import CoarseLayout

    return [Saab, Hop, HopStack, SpatialReduction, ICHM, TGHop, CoarseLayout, Material, BandStatistics, ColourClasses,
            PatchStatistics, CoocGAN]


COMPONENTS = _components()

#: Public methods that need no fit (settings' checks, sizes): every other one raises NotFittedError before fit.
NO_FIT_NEEDED = {"ICHM": {"clusters_for"}, "TGHop": {"check_channels", "check_exemplar_size", "check_settings"},
                 "CoarseLayout": {"fits", "usable_factor"}, "Material": {"stacked_channels"},
                 "CoocGAN": {"s"}}  # s: the downsampling factor its n_layers give


#: The components whose input is a 2-D array (n_samples, n_features), on which scikit-learn's checks run.
TWO_D_INPUT = {"Saab", "ICHM"}


@pytest.mark.parametrize("cls", [c for c in COMPONENTS if c.__name__ not in TWO_D_INPUT], ids=lambda c: c.__name__)
def test_components_of_images_tell_scikit_learn_its_checks_do_not_apply(cls):
    # check_estimator(TGHop()) (and of CoarseLayout, Material, BandStatistics, ColourClasses, PatchStatistics, CoocGAN)
    # ran 41 checks on 2-D arrays and failed 28 or 29 of them ("fit() takes 2 positional arguments but 3 were given",
    # "expected a fitted model, got ndarray ..."): their tags said they take (n_samples, n_features) arrays.
    with pytest.warns(SkipTestWarning, match="Can't test estimator"):
        results = check_estimator(cls(), on_fail=None)
    assert [r["check_name"] for r in results if r["status"] != "passed"] == []
    tags = cls().__sklearn_tags__().input_tags
    assert not tags.two_d_array
    assert tags.three_d_array == (cls.__name__ not in ("Hop", "HopStack", "SpatialReduction"))  # those: 4-D


#: scikit-learn's checks that feed an estimator no data (its constructor, parameters, tags, repr, clone): they apply to
#: every component, whatever its input, though check_estimator skips the components of images and 4-D arrays whole.
NO_DATA_CHECKS = ["check_estimator_cloneable", "check_estimator_tags_renamed", "check_valid_tag_types",
                  "check_estimator_repr", "check_no_attributes_set_in_init",
                  "check_do_not_raise_errors_in_init_or_set_params", "check_mixin_order",
                  "check_parameters_default_constructible", "check_get_params_invariance", "check_set_params"]


@pytest.mark.parametrize("name", NO_DATA_CHECKS)
@pytest.mark.parametrize("cls", [c for c in COMPONENTS if c.__name__ not in TWO_D_INPUT], ids=lambda c: c.__name__)
def test_components_of_images_pass_the_checks_that_feed_no_data(cls, name):
    from sklearn.utils import estimator_checks

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        getattr(estimator_checks, name)(cls.__name__, cls())


#: The second argument of ``fit`` where it is not scikit-learn's ``y``: the maps that go with a material's albedo, the
#: band statistics the colour classes are measured in (a part fitted by TGHop.fit, never alone in a pipeline).
FIT_SECOND = {"Material": "maps", "ColourClasses": "bands"}


@pytest.mark.parametrize("cls", COMPONENTS, ids=lambda c: c.__name__)
def test_fit_takes_y_as_scikit_learn_passes_it(cls):
    # BandStatistics.fit, PatchStatistics.fit and CoocGAN.fit took the image alone: fit(X, None), as a scikit-learn
    # Pipeline calls it, was "fit() takes 2 positional arguments but 3 were given".
    import inspect

    params = list(inspect.signature(cls.fit).parameters.values())[1:]
    second = params[1] if len(params) > 1 else None
    assert second is not None and second.kind is second.POSITIONAL_OR_KEYWORD
    assert second.name == FIT_SECOND.get(cls.__name__, "y")
    if second.name == "y":
        assert second.default is None


def test_the_steps_statistics_fit_the_same_with_y_none(bricks96):
    from tghop.patch_refine import PatchStatistics
    from tghop.refine import BandStatistics

    for make in (lambda: BandStatistics(), lambda: PatchStatistics(n_levels=1, rng=0)):
        one, two = make().fit(bricks96), make().fit(bricks96, None)
        assert sorted(vars(one)) == sorted(vars(two))
        assert all(np.array_equal(np.asarray(vars(one)[k], dtype=object), np.asarray(vars(two)[k], dtype=object))
                   for k in vars(one) if isinstance(vars(one)[k], np.ndarray))


def _fitted_parts(model):
    hop = model.hops_.hops_[1]
    return {"TGHop": model, "HopStack": model.hops_, "Hop": hop, "Saab": hop.saabs_[0], "SpatialReduction": model.sdr_,
            "ICHM": model.ichm_, "CoarseLayout": model.layout_, "BandStatistics": model.bands_,
            "ColourClasses": model.classes_, "PatchStatistics": model.patches_}


@pytest.mark.parametrize("cls", COMPONENTS, ids=lambda c: c.__name__)
def test_a_constructor_stores_its_parameters_and_nothing_else(cls):
    import inspect

    est = cls()
    names = [p for p in inspect.signature(cls.__init__).parameters if p != "self"]
    assert sorted(vars(est)) == sorted(names) == sorted(est.get_params(deep=False))
    assert repr(est) == f"{cls.__name__}()"
    copy = sklearn.base.clone(est)
    assert copy is not est and type(copy) is cls and copy.get_params(deep=False) == est.get_params(deep=False)
    assert est.set_params(**est.get_params(deep=False)) is est
    with pytest.raises(TGHopError, match=f"^invalid parameter 'no_such' for {cls.__name__}; valid: "):
        est.set_params(no_such=1)


@pytest.mark.parametrize("name", ["TGHop", "HopStack", "Hop", "Saab", "SpatialReduction", "ICHM", "CoarseLayout",
                                  "BandStatistics", "ColourClasses", "PatchStatistics"])
def test_a_fitted_component_keeps_its_learned_state_in_trailing_underscores_and_clones_unfitted(small_model, name):
    part = _fitted_parts(small_model)[name]
    params = part.get_params(deep=False)
    learned = [k for k in vars(part) if k not in params]
    assert learned and all(k.endswith("_") or k.startswith("_") for k in learned), learned
    assert any(k.endswith("_") and not k.startswith("_") for k in learned)
    fresh = sklearn.base.clone(part)
    assert sorted(vars(fresh)) == sorted(params)
    def same(a, b):  # a Generator is cloned as a copy
        return a is b or isinstance(a, np.random.Generator) or np.array_equal(np.asarray(a, dtype=object),
                                                                              np.asarray(b, dtype=object))

    changed = {k for k, v in fresh.get_params(deep=False).items() if not same(v, params[k])}
    assert not changed, changed


def test_a_fitted_material_keeps_its_learned_state_in_trailing_underscores_and_clones_unfitted(bricks96):
    # The test above takes TGHop's parts; a Material (its model_ a TGHop of the stacked maps) was not held to it.
    mat = Material(model=TGHop(**{**SMALL, "layout_factor": None}), rng=0).fit(bricks96, {"height": bricks96[..., 0]})
    params = mat.get_params(deep=False)
    learned = [k for k in vars(mat) if k not in params]
    assert learned and all(k.endswith("_") or k.startswith("_") for k in learned), learned
    assert mat.model is not mat.model_ and not any(k.endswith("_") for k in vars(mat.model))  # the given one unfitted
    fresh = sklearn.base.clone(mat)
    assert sorted(vars(fresh)) == sorted(params) and repr(fresh) == repr(mat)


def test_scikit_learns_check_is_fitted_agrees_with_tghops(small_model):
    # scikit-learn's check_is_fitted took a TGHop whose settings changed after fit (set_params) as fitted, where
    # every method of it raised NotFittedError: it looked at the learned state alone.
    import copy

    from sklearn.exceptions import NotFittedError as TheirNotFittedError
    from sklearn.utils.validation import check_is_fitted as their_check

    from tghop import NotFittedError

    model = copy.deepcopy(small_model)
    for part in _fitted_parts(model).values():
        their_check(part)
    for cls in COMPONENTS:
        with pytest.raises(TheirNotFittedError):
            their_check(cls())
    model.set_params(n_codewords=model.n_codewords + 1)
    with pytest.raises(NotFittedError, match="settings changed after it was fitted"):
        model.sample_patches(2, rng=0)
    with pytest.raises(TheirNotFittedError, match="This TGHop instance is not fitted yet"):
        their_check(model)
    their_check(model.set_params(n_codewords=model.n_codewords - 1))


def test_a_loaded_models_parts_have_the_parameters_they_were_fitted_with(bricks96, tmp_path):
    # A loaded model's PatchStatistics said whitening=0.0 whatever its patch_whitening, and its hops (and hop 1's
    # Saab) n_channels=None (n_components=None): get_params and clone gave settings other than the fit's.
    from tghop.modelfile import load_model, save_model

    model = TGHop(**{**SMALL, "n_channels": (6, 14)}, patch_whitening=0.5, max_patches=600).fit(bricks96)
    save_model(model, tmp_path / "m.npz")
    loaded = load_model(tmp_path / "m.npz")
    fitted, back = _fitted_parts(model), _fitted_parts(loaded)
    fitted["Saab"], back["Saab"] = model.hops_.hops_[0].saabs_[0], loaded.hops_.hops_[0].saabs_[0]  # hop 1's
    fitted["Hop 1"], back["Hop 1"] = model.hops_.hops_[0], loaded.hops_.hops_[0]  # "Hop" is hop 2
    differ = {}
    for name, part in fitted.items():
        a, b = part.get_params(deep=False), back[name].get_params(deep=False)
        differ.update({f"{name}.{k}": (a[k], b[k]) for k in a if k != "rng" and repr(a[k]) != repr(b[k])})
    assert not differ
    assert loaded.patches_.whitening == 0.5 and [h.n_channels for h in loaded.hops_.hops_] == [6, 14]


def _dummy(cls, name):
    """An argument for a required parameter ``name`` of a method of ``cls``: any that gets as far as the fit check."""
    if name in ("size", "shape"):
        return (64, 64, 3) if name == "shape" else (64, 64)
    if name in ("n", "n_samples"):
        return 4
    four_d = cls.__name__ in ("Hop", "HopStack", "SpatialReduction")
    return np.random.default_rng(0).random((4, 8, 8, 3) if four_d else (4, 8))


@pytest.mark.parametrize("cls", COMPONENTS, ids=lambda c: c.__name__)
def test_every_public_method_before_fit_is_not_fitted(cls):
    import inspect

    from sklearn.exceptions import NotFittedError as TheirNotFittedError

    from tghop import NotFittedError

    skip = {"fit", "fit_transform", "get_params", "set_params"} | NO_FIT_NEEDED.get(cls.__name__, set())
    est, checked = cls(), []
    for name in sorted(n for n in dir(cls) if not n.startswith("_") and n not in skip and not n.startswith("fit_")):
        attr = inspect.getattr_static(cls, name)
        if not (isinstance(attr, property) or inspect.isfunction(attr)):  # a class constant (CoocGAN.TILE)
            continue
        # scikit-learn's class too, here where scikit-learn is imported (test_not_fitted_is_scikit_learns_...)
        with pytest.raises(TheirNotFittedError, match=f"^[Tt]his {cls.__name__} is not (fitted|trained) yet") as caught:
            if isinstance(attr, property):
                getattr(est, name)
            else:
                method = getattr(est, name)
                required = [p.name for p in inspect.signature(method).parameters.values()
                            if p.default is p.empty and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
                method(*[_dummy(cls, p) for p in required])
        assert isinstance(caught.value, NotFittedError)
        checked.append(name)
    assert checked or cls.__name__ == "PatchStatistics"  # its one public method is fit


@pytest.mark.parametrize("cls", COMPONENTS, ids=lambda c: c.__name__)
def test_every_public_method_has_numpydoc_parameters_and_returns(cls):
    # SpatialReduction's fit, fit_transform, transform and inverse_transform, get_params, set_params and the
    # transformers' fit_transform had a line or no docstring: no Parameters nor Returns section.
    import inspect

    undocumented = []
    for name in dir(cls):
        method = inspect.getattr_static(cls, name)
        if name.startswith("_") or not inspect.isfunction(method):
            continue
        doc = inspect.getdoc(method) or ""
        takes = [p for p in inspect.signature(method).parameters if p not in ("self", "y")]
        if (takes and "\nParameters\n----" not in doc) or not ("\nReturns\n----" in doc or "\nYields\n----" in doc):
            undocumented.append(name)
    assert not undocumented


def test_not_fitted_is_scikit_learns_error_too_once_scikit_learn_is_imported_and_generation_never_imports_it():
    # `except sklearn.exceptions.NotFittedError` did not catch tghop's error: its own class, so that the
    # generation path (tghop synth) need not import scikit-learn (0.6 to 1.3 s more at start-up).
    import os
    import subprocess
    import sys

    import tghop

    script = """if True:
        import pickle, sys
        import tghop.generation
        from tghop import NotFittedError, TGHopError
        from tghop.synthesis import TGHop

        def raised():
            try:
                TGHop().sample_patches(2)
            except NotFittedError as exc:
                return exc

        plain = raised()
        assert "sklearn" not in sys.modules, "the generation path imported scikit-learn"
        assert type(plain) is NotFittedError
        import sklearn.exceptions
        try:
            TGHop().sample_patches(2)
        except sklearn.exceptions.NotFittedError as exc:
            caught = exc
        assert isinstance(caught, (NotFittedError, TGHopError, ValueError, AttributeError)), type(caught).__mro__
        assert type(caught).__name__ == "NotFittedError" and type(caught) is type(raised()), "made once"
        for exc in (plain, caught):
            back = pickle.loads(pickle.dumps(exc))  # as the plain class: made again where it is unpickled
            assert type(back) is type(caught) and back.args == exc.args
        print("ok")
    """
    env = {**os.environ, "PYTHONPATH": os.path.dirname(tghop.__path__[0])}
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0 and r.stdout == "ok\n", r.stderr[-2000:]


def test_a_scikit_learn_error_that_cannot_be_joined_leaves_tghops_error_alone(monkeypatch):
    # Its class made at the raise: a layout Python cannot join would otherwise make every raise a TypeError.
    import sys
    import types

    from tghop import NotFittedError

    class OfAnotherLayout(OSError):
        pass

    monkeypatch.setitem(sys.modules, "sklearn.exceptions", types.SimpleNamespace(NotFittedError=OfAnotherLayout))
    for _ in range(2):
        with pytest.raises(NotFittedError, match="^not fitted$") as caught:
            raise NotFittedError("not fitted")
        assert type(caught.value) is NotFittedError


def test_ichm_alone_learns_the_same_on_one_blas_thread_or_several():
    # ICHM.fit's K-means of the vectors and of the CDF codebook ran on as many BLAS threads as the process had: alone
    # (not inside TGHop.fit, which holds one), OpenBLAS's rounding by thread count gave another codebook, so a clone
    # of a fitted model's ichm_ refitted on its input learned something else.
    from threadpoolctl import threadpool_limits

    from tghop.core import ICHM

    z = np.random.default_rng(1).standard_normal((3000, 120)) @ np.random.default_rng(2).standard_normal((120, 120))
    learned = []
    for threads in (1, 2):
        with threadpool_limits(limits=threads):
            learned.append(ICHM(n_clusters=8, n_codewords=40, rng=0).fit(z)._to_arrays())
    one, two = learned
    assert sorted(one) == sorted(two)
    assert not [k for k in one if not np.array_equal(one[k], two[k])]


# ------------------------------------------------------------------ the parts' generators
# A fitted TGHop's ICHM, CoarseLayout and the layout's own TGHop (and a Material's TGHop) held the fit's Generator
# itself, used up by the fit: their repr showed it, get_params gave a live generator shared with the fit and with each
# other, and clone(part).fit(the same input) learned something else. Each now holds a copy as it was before its fit.

def _fitted_subparts(est, path):
    """Every fitted part under ``est`` (attributes ending in ``_`` with get_params, lists of them too), by path."""
    out = {}
    for name, value in vars(est).items():
        if not name.endswith("_") or name.startswith("_"):
            continue
        for i, part in enumerate(value if isinstance(value, list) else [value]):
            if callable(getattr(part, "get_params", None)):
                where = f"{path}.{name}" + (f"[{i}]" if isinstance(value, list) else "")
                out[where] = part
                out.update(_fitted_subparts(part, where))
    return out


def _recording_fits(monkeypatch, *classes):
    """Each fit of an instance of ``classes``' input, by the instance's id."""
    calls = {}
    for cls in classes:
        def spy(self, *args, _fit=cls.fit, **kwargs):
            calls[id(self)] = (args, kwargs)
            return _fit(self, *args, **kwargs)
        monkeypatch.setattr(cls, "fit", spy)
    return calls


def _assert_same_arrays(a, b, what):
    assert sorted(a) == sorted(b), what
    differ = [k for k in a if not np.array_equal(a[k], b[k])]
    assert not differ, f"{what}: {differ[:5]}"


def _assert_no_shared_generator(parts, given):
    """No part's parameters hold ``given`` (the fit's Generator) or a Generator another part holds."""
    seen = {}
    for where, part in parts.items():
        for k, v in part.get_params(deep=False).items():
            if isinstance(v, np.random.Generator):
                assert v is not given, f"{where}.{k} is the fit's own generator"
                assert id(v) not in seen, f"{where}.{k} is {seen[id(v)]}'s generator too"
                seen[id(v)] = f"{where}.{k}"
    return seen


def test_a_fitted_parts_clone_refitted_on_its_input_learns_it_again(bricks96, monkeypatch, tmp_path):
    from tghop.core import ICHM
    from tghop.modelfile import load_model, save_model
    from tghop.synthesis import CoarseLayout

    calls = _recording_fits(monkeypatch, ICHM, CoarseLayout, TGHop)
    given = np.random.default_rng(5)
    model = TGHop(**{**SMALL, "rng": given, "max_patches": 200}).fit(bricks96)
    after = given.bit_generator.state
    assert model.layout_ is not None
    parts = _fitted_subparts(model, "model")
    held = _assert_no_shared_generator(parts, given)
    assert {"model.ichm_.rng", "model.layout_.rng", "model.layout_.model_.rng", "model.layout_.model_.ichm_.rng"} \
        <= set(held.values())
    assert "Generator" in repr(model.ichm_) and repr(model.ichm_.rng) != repr(given)
    for where in ("model.ichm_", "model.layout_", "model.layout_.model_", "model.layout_.model_.ichm_"):
        part = parts[where]
        args, kwargs = calls[id(part)]
        again = sklearn.base.clone(part).fit(*args, **kwargs)
        state = (lambda p: p.model_) if isinstance(part, CoarseLayout) else (lambda p: p)
        _assert_same_arrays(state(part)._to_arrays(), state(again)._to_arrays(), where)
    assert given.bit_generator.state == after  # refitting the parts drew nothing from the fit's generator
    # Loaded, the parts held rng=None where the fitted ones held their generators: get_params, clone and repr said
    # otherwise than the fit. The file records each part's generator; a loaded part's clone learns it again too.
    save_model(model, tmp_path / "m.npz")
    loaded = _fitted_subparts(load_model(tmp_path / "m.npz"), "model")
    assert sorted(loaded) == sorted(parts)
    for where, part in loaded.items():
        theirs = parts[where].get_params(deep=False).get("rng")
        ours = part.get_params(deep=False).get("rng")
        if not isinstance(theirs, np.random.Generator):
            assert ours == theirs, where
            continue
        assert isinstance(ours, np.random.Generator) and ours is not theirs, where
        assert ours.bit_generator.state == theirs.bit_generator.state and repr(part) == repr(parts[where]), where
    args, kwargs = calls[id(parts["model.ichm_"])]
    again = sklearn.base.clone(loaded["model.ichm_"]).fit(*args, **kwargs)
    _assert_same_arrays(parts["model.ichm_"]._to_arrays(), again._to_arrays(), "loaded model.ichm_")


def test_a_materials_model_holds_its_own_generator_as_it_was_before_the_fit(bricks96, monkeypatch, tmp_path):
    calls = _recording_fits(monkeypatch, TGHop)
    given = np.random.default_rng(6)
    mat = Material(model=TGHop(**{**SMALL, "layout_factor": None}), rng=given).fit(
        bricks96, {"height": bricks96.mean(axis=2)})
    _assert_no_shared_generator(_fitted_subparts(mat, "material"), given)
    assert isinstance(mat.model_.rng, np.random.Generator) and mat.get_params()["rng"] is given
    args, kwargs = calls[id(mat.model_)]
    _assert_same_arrays(mat.model_._to_arrays(), sklearn.base.clone(mat.model_).fit(*args, **kwargs)._to_arrays(),
                        "material.model_")
    seeded = Material(model=TGHop(**{**SMALL, "layout_factor": None}), rng=3).fit(bricks96)
    assert seeded.model_.rng == 3  # an int seed stays one (the model file records it)
    from tghop.modelfile import load_model, save_model

    save_model(mat, tmp_path / "m.npz")  # loaded, the joint model held rng=None: it holds the fitted one's generator
    back = load_model(tmp_path / "m.npz", material=True)
    assert back.model_.rng.bit_generator.state == mat.model_.rng.bit_generator.state
    assert repr(back.model_) == repr(mat.model_) and "Generator(PCG64, seed=6" in repr(back.model_)
    save_model(seeded, tmp_path / "s.npz")
    assert load_model(tmp_path / "s.npz", material=True).model_.rng == 3



def test_a_generators_repr_is_the_same_in_every_fit_run_and_process(bricks96):
    # A fitted part's repr named its copy of the fit's generator by address (rng=Generator(PCG64) at 0x7f...):
    # two fits of the same seed, in one process or two, printed different reprs. It now says the generator's seed.
    def reprs(rng):
        model = TGHop(**{**SMALL, "rng": rng, "max_patches": 200})
        before = repr(model)
        model.fit(bricks96)
        return [before] + [f"{where}: {part!r}" for where, part in _fitted_subparts(model, "model").items()]

    for rng in (0, lambda: np.random.default_rng(7)):
        one, two = (reprs(rng() if callable(rng) else rng) for _ in range(2))
        assert one == two and not [r for r in one if " at 0x" in r], one
    shown = "\n".join(one)
    assert one[0] == ("TGHop(gamma=0.01, max_patches=200, n_channels=(9, 22), n_clusters=8, n_codewords=40, "
                      "rng=Generator(PCG64, seed=7), stride=4)")  # before the fit; after it, drawn from:
    assert "model.ichm_: ICHM(n_clusters=8, n_codewords=40, rng=Generator(PCG64, seed=7, advanced))" in shown
    from tghop._estimator import generator_text

    assert generator_text(np.random.default_rng()) == "Generator(PCG64)"  # unseeded: no seed to show
    assert generator_text(np.random.default_rng(np.random.SeedSequence(3).spawn(1)[0])) == "Generator(PCG64)"
    assert repr(Material(rng=np.random.default_rng(2))) == "Material(rng=Generator(PCG64, seed=2))"


def test_a_scikit_learn_users_random_state_is_told_it_is_rng(small_model):
    # 0.58 named the type alone ("got RandomState") and listed rng among the valid parameters without a word;
    # a RandomState, SeedSequence or BitGenerator is what numpy.random.default_rng takes.
    for given in (np.random.RandomState(0), np.random.SeedSequence(0), np.random.PCG64(0)):
        with pytest.raises(TGHopError, match=r"got (RandomState|SeedSequence|PCG64); give "
                                             r"numpy.random.default_rng\(rng\) of it, or an int seed$"):
            small_model.sample_patches(2, rng=given)
    with pytest.raises(TGHopError, match=r"^invalid parameter 'random_state' for TGHop; scikit-learn's random_state is "
                                         r"tghop's rng; valid: "):
        TGHop().set_params(random_state=0)
    with pytest.raises(TGHopError, match=r"^invalid parameter 'random_state' for Saab; valid: "):  # no rng: no hint
        Saab().set_params(random_state=0)


@pytest.mark.parametrize("name, said", [
    ("k1", "the command line's --k1 is n_channels=(K1, K2[, K3]) here"),
    ("clusters", "the command line's --clusters is n_clusters here"),
    ("fit_seed", "the command line's --fit-seed is rng here"),
    ("layout", "the command line's --layout is layout_factor here"),
    ("pool", "the command line's --pool is synthesize()'s n_patches, given per image: "
             "model.synthesize(size, n_patches=...)"),
    ("refine", "refine is synthesize()'s refine, given per image: model.synthesize(size, refine=...)"),
])
def test_a_command_line_users_option_name_is_told_its_python_name(name, said):
    # a user of tghop fit --k1 9 --clusters 60 who turns to Python: 0.62 listed the valid names alone, which hold
    # neither k1 nor fit_seed, and said nothing of a generation setting given to the estimator
    with pytest.raises(TGHopError) as error:
        TGHop().set_params(**{name: 1})
    assert str(error.value).startswith(f"invalid parameter {name!r} for TGHop; {said}; valid: "), str(error.value)
    with pytest.raises(TGHopError, match=r"^invalid parameter 'k1' for Saab; valid: "):  # not a TGHop: no hint
        Saab().set_params(k1=0)
    # ... and to the constructor (0.64; 0.63 let Python's bare "unexpected keyword argument 'k1'" out): a TypeError,
    # as Python's, with set_params' words
    with pytest.raises(TypeError) as error:
        TGHop(**{name: 1})
    assert str(error.value).startswith(f"TGHop() got an unexpected keyword argument {name!r}; {said}; valid: "), \
        str(error.value)


def test_a_constructor_given_an_unknown_keyword_names_the_valid_ones_and_a_models_setting_its_place():
    with pytest.raises(TypeError, match=r"^Saab\(\) got an unexpected keyword argument 'k1'; valid: n_components$"):
        Saab(k1=0)
    with pytest.raises(TypeError, match=r"^Material\(\) got an unexpected keyword argument 'gamma'; gamma is its "
                                        r"model's: Material\(model=TGHop\(gamma=...\)\); valid: model, normal, rng$"):
        Material(gamma=0.01)
    with pytest.raises(TypeError, match=r"^Material\(\) got an unexpected keyword argument 'k1'; a setting of its "
                                        r"model, Material\(model=TGHop\(...\)\); the command line's --k1 is "):
        Material(k1=9)
    assert TGHop(gamma=0.01).gamma == 0.01 and Material(rng=1).rng == 1  # the constructor's own keywords as ever


@pytest.mark.parametrize("name, said", [
    ("pool", "the command line's --pool is n_patches here"),
    ("k1", "the command line's --k1 is a fit setting: TGHop(n_channels=(K1, K2[, K3])), fitted again"),
    ("clusters", "the command line's --clusters is a fit setting: TGHop(n_clusters=...), fitted again"),
    ("gamma", "gamma is a fit setting: TGHop(gamma=...), fitted again"),
])
def test_synthesize_given_a_command_line_name_or_a_fit_setting_says_its_place(small_model, name, said):
    # 0.63: Python's bare "TGHop.synthesize() got an unexpected keyword argument 'pool'" (0.64)
    with pytest.raises(TypeError) as error:
        small_model.synthesize((40, 40), **{name: 1})
    assert str(error.value) == f"TGHop.synthesize() got an unexpected keyword argument {name!r}; {said}"


@pytest.mark.parametrize("make, use, said", [
    (TGHop, lambda m: m.synthesize((64, 64)), "call 'fit' with an exemplar first (or load a fitted model with "
                                              "tghop.modelfile.load_model)"),
    (Material, lambda m: m.synthesize((64, 64)), "call 'fit' with an albedo and its maps first (or load a fitted "
                                                 "material with tghop.modelfile.load_model)"),
    (Saab, lambda m: m.transform(np.zeros((4, 12))), "call its 'fit' first, or take the fitted part of a fitted TGHop"),
    (HopStack, lambda m: m.transform(np.zeros((2, 32, 32, 3))), "call its 'fit' first, or take the fitted part of"),
])
def test_before_fit_each_estimator_says_what_its_fit_takes(make, use, said):
    # a researcher's Saab or ICHM was told "call 'fit' with an exemplar first (or load a fitted model with
    # tghop.modelfile.load_model)" (0.62), though its fit takes arrays and no model file holds one alone;
    # a Material's fit takes an albedo and its maps
    from tghop import NotFittedError

    with pytest.raises(NotFittedError) as error:
        use(make())
    assert str(error.value) == f"this {make.__name__} is not fitted yet; {said}" or \
        str(error.value).startswith(f"this {make.__name__} is not fitted yet; {said}"), str(error.value)
