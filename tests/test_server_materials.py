"""Whole materials on ``tghop serve`` (a real uvicorn server, httpx as the client): an albedo
fitted with its maps (``map:<name>`` fields), a material's images as JSON of every map at its
depth (the library's maps, bit for bit), a material file uploaded, painted and remixed, and
each request a material cannot take refused in one line."""

import base64
import json

import numpy as np
import pytest

httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")

from conftest import FAST_FIT, png  # noqa: E402

from tghop import data  # noqa: E402
from tghop.imageio import to_uint8, to_uint16  # noqa: E402
from tghop.material import example_maps  # noqa: E402
from tghop.modelfile import load_model  # noqa: E402

SIZE = 96


def decode(data_b64: str) -> np.ndarray:
    """A base64 PNG's pixels at its depth: uint8 or uint16 (Pillow reads 16-bit RGB as 8 bits)."""
    import tempfile

    from tghop.imageio import load_image

    with tempfile.TemporaryDirectory() as folder:
        path = f"{folder}/map.png"
        with open(path, "wb") as fh:
            fh.write(base64.b64decode(data_b64))
        image, depth = load_image(path, dtype=None, with_depth=True)
        return to_uint16(image) if depth == 16 else image


@pytest.fixture(scope="module")
def client(live_server):
    with httpx.Client(base_url=live_server.url, timeout=120) as c:
        yield c


def map_files(albedo=None):
    """The example maps of the built-in bricks as uploads: normal at 16 bits, height at 8."""
    maps = example_maps(data.bricks(SIZE) if albedo is None else albedo)
    return {"map:normal": ("bricks_normal.png", png(to_uint16(maps["normal"]))),
            "map:height": ("height.png", png(to_uint8(maps["height"][..., 0])))}


def albedo_file():
    return {"image": ("bricks.png", png(to_uint8(data.bricks(SIZE))))}


def fit(client, files, *, with_notes=False):
    r = client.post("/api/models", files={**files, **{k: (None, v) for k, v in FAST_FIT.items()}})
    assert r.status_code in (200, 202), r.text
    body = r.json()
    deadline = 120
    while True:
        state = client.get(f"/api/jobs/{body['job']}").json()
        if state["state"] in ("done", "failed", "cancelled"):
            break
        deadline -= 0.1
        assert deadline > 0
        import time

        time.sleep(0.1)
    assert state["state"] == "done", state
    return (body["id"], body["notes"]) if with_notes else body["id"]


@pytest.fixture(scope="module")
def material_id(client):
    return fit(client, {**albedo_file(), **map_files()})


def assert_error(r, status, *words):
    assert r.status_code == status, (r.status_code, r.text)
    message = r.json()["error"]
    assert "\n" not in message and "Traceback" not in message
    for word in words:
        assert word in message, message
    return message


def test_a_fit_with_maps_is_a_material_named_by_its_maps(client, material_id):
    summary = client.get(f"/api/models/{material_id}").json()
    assert summary["material"]["maps"] == [
        {"name": "albedo", "channels": 3, "normal": False, "depth": 8},
        {"name": "normal", "channels": 3, "normal": True, "depth": 16},
        {"name": "height", "channels": 1, "normal": False, "depth": 8}]
    assert summary["exemplar_shape"][:2] == [SIZE, SIZE]
    # the levels of its albedo's patch statistics (the page's quality switch), as the file's metadata says them
    # (0.61: one count, Material.albedo_patch_levels, where the server had its own copy)
    import io

    saved = load_model(io.BytesIO(client.get(f"/api/models/{material_id}/file").content), material=True)
    assert summary["material"]["patch_levels"] == saved.albedo_patch_levels() == saved._state_meta()["material"][
        "patch_levels"] == len(saved.patches_.directions_) > 0
    # The joint model's channels are the defaults for its 7 stacked channels, as tghop fit --maps gives
    # (K1 = 3 per channel), not those of a 3-colour exemplar (9)
    assert summary["exemplar_shape"][2] == 7 and summary["channels"][0] == 21
    # The same albedo without maps is another model; the same maps again are the same material
    assert fit(client, {**albedo_file(), **map_files()}) == material_id
    plain = fit(client, albedo_file())
    assert plain != material_id and "material" not in client.get(f"/api/models/{plain}").json()


def test_a_materials_images_are_every_map_at_its_depth_as_the_library_makes_them(client, material_id, tmp_path):
    from tghop.imageio import to_uint8 as u8, to_uint16 as u16

    r = client.post(f"/api/models/{material_id}/images", json={"size": [40, 56], "seed": 5, "refine": 2})
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("application/json") and r.headers["x-tghop-seed"] == "5"
    body = r.json()
    assert body["size"] == [40, 56] and body["seed"] == 5
    assert [(m["name"], m["suffix"], m["depth"], m["normal"]) for m in body["maps"]] == [
        ("albedo", None, 8, False), ("normal", "normal", 16, True), ("height", "height", 8, False)]
    got = {m["name"]: decode(m["png"]) for m in body["maps"]}
    assert got["albedo"].shape == (40, 56, 3) and got["albedo"].dtype == np.uint8
    assert got["normal"].shape == (40, 56, 3) and got["normal"].dtype == np.uint16
    assert got["height"].shape == (40, 56, 1)
    # The library's maps from the downloaded file, bit for bit
    path = tmp_path / "m.npz"
    path.write_bytes(client.get(f"/api/models/{material_id}/file").content)
    want = load_model(path, material=True).synthesize((40, 56), rng=5, refine=2, dtype=np.float32)
    np.testing.assert_array_equal(got["albedo"], u8(want["albedo"]))
    np.testing.assert_array_equal(got["normal"], u16(want["normal"]))
    np.testing.assert_array_equal(got["height"][..., 0], u8(want["height"]))
    # Unit normals, decoded
    n = got["normal"].astype(float) / 65535 * 2 - 1
    np.testing.assert_allclose(np.linalg.norm(n, axis=2), 1.0, atol=1e-3)
    again = client.post(f"/api/models/{material_id}/images", json={"size": [40, 56], "seed": 5, "refine": 2})
    assert again.json()["maps"] == body["maps"]
    # Asked for multipart (as the page asks): the same PNGs as files, after the JSON without them
    r = client.post(f"/api/models/{material_id}/images", json={"size": [40, 56], "seed": 5, "refine": 2},
                    headers={"Accept": "multipart/form-data, application/json"})
    assert r.status_code == 200 and r.headers["content-type"].startswith("multipart/form-data; boundary=")
    parts = multipart_parts(r)
    assert list(parts) == ["_meta", "albedo", "normal", "height"]
    meta = json.loads(parts["_meta"][1])
    assert meta == {"size": [40, 56], "seed": 5, "maps": [{k: v for k, v in m.items() if k != "png"}
                                                         for m in body["maps"]]}
    for m in body["maps"]:
        assert parts[m["name"]] == (f"{m['name']}.png", base64.b64decode(m["png"]))


def multipart_parts(response) -> dict:
    """A multipart/form-data answer's parts: name -> (filename or None, bytes), in order."""
    from email.parser import BytesParser
    from email.policy import HTTP

    message = BytesParser(policy=HTTP).parsebytes(
        b"Content-Type: " + response.headers["content-type"].encode() + b"\r\n\r\n" + response.content)
    return {part.get_param("name", header="content-disposition"): (part.get_filename(), part.get_payload(decode=True))
            for part in message.iter_parts()}


def test_a_material_file_uploads_and_paints(client, material_id):
    content = client.get(f"/api/models/{material_id}/file").content
    r = client.post("/api/models/upload", content=content, headers={"Content-Type": "application/octet-stream"})
    assert r.status_code == 200, r.text
    uploaded = r.json()["id"]
    assert client.get(f"/api/models/{uploaded}").json()["material"]["maps"][1]["name"] == "normal"
    guide = np.zeros((48, 64), dtype=np.uint8)
    guide[:, 32:] = 255
    body = {"models": [material_id, uploaded], "guide": base64.b64encode(png(guide)).decode(), "seed": 3}
    r = client.post("/api/images/guided", json=body)
    assert r.status_code == 200, r.text
    maps = r.json()["maps"]
    assert [m["name"] for m in maps] == ["albedo", "normal", "height"]
    assert decode(maps[1]["png"]).shape == (48, 64, 3) and maps[1]["depth"] == 16
    remix = client.post("/api/images/guided", json={"models": [material_id, uploaded], "size": [48, 64], "seed": 3})
    assert remix.status_code == 200, remix.text
    assert len(remix.json()["maps"]) == 3


def test_quality_best_patch_refines_a_materials_albedo(client, material_id, tmp_path):
    # 0.58 refused it for every material ("a material has no patch statistics"); 0.59 fits the albedo's
    from conftest import save_material

    assert client.get(f"/api/models/{material_id}").json()["material"]["patch_levels"] > 0
    url, ask = f"/api/models/{material_id}/images", {"size": [48, 48], "seed": 3}
    made = {}
    for quality in ("default", "best"):
        r = client.post(url, json={**ask, "quality": quality})
        assert r.status_code == 200, r.text
        made[quality] = {m["name"]: decode(m["png"]) for m in r.json()["maps"]}
    assert not np.array_equal(made["default"]["albedo"], made["best"]["albedo"])
    for name in ("normal", "height"):  # the other maps as the default's, bit for bit
        assert np.array_equal(made["default"][name], made["best"][name])
    # A material without them (tghop 0.58's, or fitted with patch_levels 0): refused naming the refit
    save_material(tmp_path / "old.npz", patch_levels=0)
    r = client.post("/api/models/upload", content=(tmp_path / "old.npz").read_bytes(),
                    headers={"Content-Type": "application/octet-stream"})
    old = r.json()["id"]
    assert client.get(f"/api/models/{old}").json()["material"]["patch_levels"] == 0
    for bad in ({"quality": "best"}, {"patch_refine": 4}):
        assert_error(client.post(f"/api/models/{old}/images", json={"size": [32, 32], **bad}), 422,
                     "is a material without patch statistics of its albedo", "fit it again")
    assert client.post(f"/api/models/{old}/images", json={"size": [32, 32]}).status_code == 200
    # Painted or remixed materials (0.60; 0.59: a 422): each albedo refined by its own material, the other maps kept
    remixed = {}
    for quality in ("default", "best"):
        r = client.post("/api/images/guided", json={"models": [material_id, material_id], "size": [32, 32],
                                                    "seed": 3, "quality": quality})
        assert r.status_code == 200, r.text
        remixed[quality] = {m["name"]: decode(m["png"]) for m in r.json()["maps"]}
    assert not np.array_equal(remixed["default"]["albedo"], remixed["best"]["albedo"])
    assert all(np.array_equal(remixed["default"][name], remixed["best"][name]) for name in ("normal", "height"))
    assert_error(client.post("/api/images/guided", json={"models": [old, old], "size": [32, 32], "quality": "best"}),
                 422, "models[0] is a material without patch statistics of its albedo")


def test_what_a_material_cannot_do_is_refused_in_one_line(client, material_id):
    plain = fit(client, albedo_file())
    picture = png(to_uint8(data.bricks(48)))
    mask = np.zeros((48, 48), dtype=np.uint8)
    mask[10:30, 10:30] = 255
    # A material's fill needs its maps, all of them and no others; a texture model's takes none
    # (0.61: which one is wrong, said first; 0.60 said the list alone, also of a map named in another case)
    assert_error(client.post(f"/api/models/{material_id}/inpaint", files={
        "image": ("p.png", picture), "mask": ("m.png", png(mask))}), 400,
        "the map 'normal' was not sent; this material's maps are normal, height")
    assert_error(client.post(f"/api/models/{material_id}/extend", files={
        "image": ("p.png", picture), "size": (None, "64x64"), "map:normal": ("n.png", picture),
        "map:rough": ("r.png", picture)}), 400, "map:rough is no map of this material; this material's maps are "
        "normal, height")
    assert_error(client.post(f"/api/models/{material_id}/extend", files={
        "image": ("p.png", picture), "size": (None, "64x64"), "map:Normal": ("n.png", picture),
        "map:height": ("h.png", picture)}), 400, "map:Normal names its map 'normal' in another case (a field's name "
        "is matched as it is); this material's maps are normal, height")
    strip = png(to_uint8(data.bricks(48))[:8])  # an 8x48 picture grown to 8x96: thinner than a patch
    assert_error(client.post(f"/api/models/{material_id}/extend", files={
        "image": ("p.png", strip), "size": (None, "8x96"), "map:normal": ("n.png", strip),
        "map:height": ("h.png", strip)}), 400,  # 0.62: the page's words, as a texture's (0.61: the library's)
        "the picture p.png (8x48) grown to 8x96 is thinner than the model's 32x32 patches; grow it to at least 32x96")
    assert_error(client.post(f"/api/models/{plain}/inpaint", files={
        "image": ("p.png", picture), "mask": ("m.png", png(mask)), "map:height": ("h.png", picture)}),
        422, "is a texture model; map:<name> fields go with a material")
    # A morph of a material with a texture model, in a person's words (the page's A and B, the id's start as the
    # page lists the model; what to do), not the API's field name ("a is a material")
    assert_error(client.post("/api/images/morph", json={"a": material_id, "b": plain, "size": [32, 64]}),
                 422, f"B ({plain[:8]}) is a texture model but A ({material_id[:8]}) is a material; morph two "
                 "materials (with the same maps) or two texture models")
    assert_error(client.post("/api/images/morph", json={"a": plain, "b": material_id, "size": [32, 64]}),
                 422, f"B ({material_id[:8]}) is a material but A ({plain[:8]}) is a texture model")
    # Named as the request and the page name them (models[i], the start of the id)
    assert_error(client.post("/api/images/guided", json={"models": [material_id, plain], "size": [32, 32]}),
                 422, f"models[1] ({plain[:8]}) is a texture model but models[0] ({material_id[:8]}) is a material")
    assert_error(client.post("/api/images/guided", json={"models": [plain, material_id], "size": [32, 32]}),
                 422, f"models[1] ({material_id[:8]}) is a material but models[0] ({plain[:8]}) is a texture model")


def test_materials_with_other_maps_are_not_painted_together(client, material_id):
    other = fit(client, {**albedo_file(), "map:normal": map_files()["map:normal"]})
    assert_error(client.post("/api/images/guided", json={"models": [material_id, other], "size": [32, 32]}),
                 422, f"models[1] ({other[:8]}) has the maps normal but models[0]", "the same maps")
    assert_error(client.post("/api/images/morph", json={"a": material_id, "b": other, "size": [32, 64]}),
                 422, f"B ({other[:8]}) has the maps normal but A ({material_id[:8]}) has normal, height; give "
                 "materials with the same maps, matched by their kinds")
    # the same maps in another order: 0.60 said "B has the maps albedo, height, normal but A has albedo, normal,
    # height"
    files = map_files()
    turned = fit(client, {**albedo_file(), "map:height": files["map:height"], "map:normal": files["map:normal"]})
    for route, body, who in (("morph", {"a": material_id, "b": turned, "size": [32, 64]}, ("B", "A")),
                             ("guided", {"models": [material_id, turned], "size": [32, 32]},
                              ("models[1]", "models[0]"))):
        assert_error(client.post(f"/api/images/{route}", json=body), 422,
                     f"{who[0]} ({turned[:8]}) has its maps in another order (height, normal) than {who[1]} "
                     f"({material_id[:8]}) (normal, height); fit it again with its maps (the fields map:NAME) in that "
                     "order: normal, height")


def test_two_materials_morph_every_map_as_the_library_morphs_them(client, material_id, tmp_path):
    # 0.59's tghop morph took two materials, but the server refused them (422: "a morph goes between two texture
    # models"): every map of the strip, as the library makes it from the downloaded files, bit for bit.
    from tghop.guided import morph
    from tghop.imageio import to_uint8 as u8, to_uint16 as u16

    other = fit(client, {"image": ("cells.png", png(to_uint8(data.builtin("cells")[:SIZE, :SIZE]))),
                         **map_files(data.builtin("cells")[:SIZE, :SIZE])})
    r = client.post("/api/images/morph", json={"a": material_id, "b": other, "size": [32, 96], "seed": 2,
                                               "refine": 2})
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("application/json") and r.headers["x-tghop-seed"] == "2"
    body = r.json()
    assert body["size"] == [32, 96] and [m["name"] for m in body["maps"]] == ["albedo", "normal", "height"]
    got = {m["name"]: decode(m["png"]) for m in body["maps"]}
    models = []
    for name, model_id in (("a", material_id), ("b", other)):
        (tmp_path / f"{name}.npz").write_bytes(client.get(f"/api/models/{model_id}/file").content)
        models.append(load_model(tmp_path / f"{name}.npz", material=True))
    want = morph(*models, (32, 96), rng=2, refine=2, dtype=np.float32)
    np.testing.assert_array_equal(got["albedo"], u8(want["albedo"]))
    np.testing.assert_array_equal(got["normal"], u16(want["normal"]))
    np.testing.assert_array_equal(got["height"][..., 0], u8(want["height"]))
    r = client.post("/api/images/morph", json={"a": material_id, "b": other, "size": [32, 96], "seed": 2,
                                               "refine": 2}, headers={"Accept": "multipart/form-data"})
    assert list(multipart_parts(r)) == ["_meta", "albedo", "normal", "height"]  # as the page asks for it


@pytest.mark.parametrize("files, words", [
    ({"map:normal": ("n.png", png(np.zeros((SIZE, SIZE + 8, 3), dtype=np.uint8)))},
     ["the map normal (n.png) is 96x104", "albedo is 96x96"]),
    ({"map:my map": ("n.png", b"x")}, ["the map name 'my map'"]),
    # 0.59: "must be letters, digits, '.', '_' or '-', ..." of a name of letters alone, over 64 of them
    ({"map:" + "n" * 300: ("n.png", b"x")}, ["is 300 characters, more than the 64 a map's name may have", "shorten"]),
    ({"map:Albedo": ("n.png", b"x")}, ["a map is named 'Albedo', the albedo's name in another case; give each map "
                                       "its own name (fields map:NAME)"]),
    # 0.60: "two maps are named 'Normal' (or a map is named albedo); name each map once", not a word of case
    ({"map:normal": ("n.png", b"x"), "map:Normal": ("m.png", b"x")},
     ["two maps are named 'normal' and 'Normal', which differ only in case", "not only in case (fields map:NAME)"]),
    ({"map:normal": (None, "text")}, ["'map:normal' must be a file upload"]),
    ({"map:normal": ("n.png", b"")}, ["the map normal (n.png) is empty"]),
    ({"map:normal": ("n.png", b"not an image")}, ["n.png"]),
    # Unity's mask map (smoothness in A): its alpha was dropped as transparency, the material without it
    ({"map:mask": ("Rock_MaskMap.png",
                   png(np.dstack([to_uint8(data.bricks(SIZE)), np.full((SIZE, SIZE), 9, np.uint8)])))},
     ["the map mask (Rock_MaskMap.png) has an alpha channel that holds data (100% of its pixels not opaque"]),
])
def test_bad_maps_are_refused_before_a_fit_starts(client, files, words):
    r = client.post("/api/models", files={**albedo_file(), **files, **{k: (None, v) for k, v in FAST_FIT.items()}})
    assert_error(r, 400, *words)


@pytest.mark.parametrize("exemplar, maps, words", [
    # the colour map among the maps, the exemplar another kind: the two swapped (0.57, as tghop fit --maps)
    ("Rock_Roughness.png", ["Rock_Color", "Rock_NormalGL"],
     ["the exemplar Rock_Roughness.png is named as a roughness map and the map Rock_Color as the colour map",
      "send Rock_Color's file as the exemplar and Rock_Roughness.png as a map"]),
    # a normal map as the exemplar and no colour map: its vectors would be fitted as colours
    ("rock_nor_gl_2k.png", ["rock_rough"],
     ["the exemplar rock_nor_gl_2k.png is named as a normal map and no map as the colour map",
      "send the material's colour map as the exemplar"]),
])
def test_a_colour_map_out_of_place_is_refused_before_a_fit_starts(client, exemplar, maps, words):
    image = to_uint8(data.bricks(SIZE))
    files = {"image": (exemplar, png(image)), **{f"map:{name}": (f"{name}.png", png(image)) for name in maps}}
    message = assert_error(client.post("/api/models", files={**files, **{k: (None, v) for k, v in FAST_FIT.items()}}),
                           400, *words)
    assert "--maps" not in message and "tghop fit" not in message  # the page's words


def test_a_materials_exemplar_named_as_another_map_is_still_fitted_without_a_colour_map(client):
    # a material may have no colour map: tghop fit --maps and a batch row warn, and fit it; the server said nothing
    # (0.57), now the fit's notes say it in the page's words
    image = to_uint8(data.bricks(SIZE))
    model, notes = fit(client, {"image": ("Rock_Roughness.png", png(image)), "map:Rock_Height": ("h.png", png(image))},
                       with_notes=True)
    assert model
    said = [n for n in notes if "colour map" in n]
    assert len(said) == 1 and said[0].startswith(
        "the exemplar Rock_Roughness.png is named as a roughness map and no map as the colour map; it is fitted as "
        "the colour map"), notes
    assert "--maps" not in said[0] and "tghop fit" not in said[0]


def test_a_maps_name_says_its_kind_before_its_files(client):
    # a map's kind is its name's (the field's), else its file's: a colour map sent under a name of no kind is
    # still the colour map among the maps
    image = png(to_uint8(data.bricks(SIZE)))
    files = {"image": ("Rock_Roughness.png", image), "map:layer": ("Rock_Color.png", image)}
    assert_error(client.post("/api/models", files={**files, **{k: (None, v) for k, v in FAST_FIT.items()}}), 400,
                 "the exemplar Rock_Roughness.png is named as a roughness map and the map layer as the colour map")


def test_a_materials_channel_count_out_of_range_is_refused_before_a_fit_starts(client):
    # K1 above what the stacked channels hold (albedo 3 + normal 3 + height 1 = 7: at most 28), as a
    # texture fit's: 422 naming the form field, not the job failing with the command line's --k1
    fields = {**albedo_file(), **map_files(), **{k: (None, v) for k, v in FAST_FIT.items()}, "k1": (None, "1000")}
    message = assert_error(client.post("/api/models", files=fields), 422, "K1 (k1) is 1000",
                           "7 channels has 28; choose at most 28", "albedo 3, normal 3, height 1")
    assert "--k1" not in message
    # Within the stack's range though over the albedo's (12): fitted
    material = fit(client, {**albedo_file(), **map_files(), "k1": (None, "20")})
    assert client.get(f"/api/models/{material}").json()["channels"][0] == 20


def test_more_maps_than_a_material_takes_are_refused(client):
    one = png(to_uint8(data.bricks(SIZE))[..., 0])
    files = {f"map:m{i}": (f"m{i}.png", one) for i in range(9)}
    assert_error(client.post("/api/models", files={**albedo_file(), **files}), 400, "at most 8")


def test_a_fit_with_maps_may_send_more_than_one_files_limit_but_no_file_over_it(client):
    # Two maps of 30 MB each: over 50 MB together, within the fit's 200 MB (they are no images: 400, not 413)
    files = {**albedo_file(), "map:a": ("a.png", b"\0" * (30 << 20)), "map:b": ("b.png", b"\0" * (30 << 20))}
    assert_error(client.post("/api/models", files=files), 400, "a.png")
    files = {**albedo_file(), "map:a": ("a.png", b"\0" * ((50 << 20) + 10))}
    assert_error(client.post("/api/models", files=files), 413, "a.png is over the limit of 50 MB a file")


def test_a_normal_map_that_holds_no_unit_vectors_is_refused_before_a_fit_starts(client):
    grey = png(to_uint8(data.bricks(SIZE)))  # named normal, but colours
    r = client.post("/api/models", files={**albedo_file(), "map:normal": ("n.png", grey)})
    assert_error(r, 400, "n.png: map 'normal' is a normal map by its name but its pixels are not unit vectors")


def test_a_normal_map_stored_turned_is_turned_with_its_vectors_or_refused_in_one_line(client, material_id):
    # Its pixels were turned upright by the EXIF orientation, its vectors not (lit wrong); a quarter turn needs
    # the map's convention, which a flat map's content does not say.
    import io

    from PIL import Image

    flat = np.zeros((SIZE, SIZE, 3), np.uint8)
    flat[...] = (128, 128, 255)
    exif = Image.Exif()
    exif[274] = 6
    buf = io.BytesIO()
    Image.fromarray(flat).save(buf, format="PNG", exif=exif)
    r = client.post("/api/models", files={**albedo_file(), "map:normal": ("n.png", buf.getvalue())})
    assert_error(r, 400, "the map normal (n.png) is stored turned (EXIF orientation 6)")
    hole = np.zeros((SIZE, SIZE), np.uint8)
    hole[30:60, 20:70] = 255
    r = client.post(f"/api/models/{material_id}/inpaint", files={
        "image": ("p.png", png(to_uint8(data.bricks(SIZE)))), "mask": ("m.png", png(hole)),
        "map:normal": ("n.png", buf.getvalue()), "map:height": map_files()["map:height"]})
    assert_error(r, 400, "the map normal (n.png) is stored turned (EXIF orientation 6)")


def test_a_materials_hole_is_filled_in_every_map_as_the_library_fills_it(client, material_id, tmp_path):
    from tghop.inpaint import inpaint_material

    albedo = to_uint8(data.bricks(SIZE, rng=8))
    maps = example_maps(albedo)
    hole = np.zeros((SIZE, SIZE), dtype=bool)
    hole[30:60, 20:70] = True
    files = {"image": ("p.png", png(albedo)), "mask": ("m.png", png(hole.astype(np.uint8) * 255)),
             "map:normal": ("n.png", png(to_uint16(maps["normal"]))),
             "map:height": ("h.png", png(to_uint8(maps["height"])))}
    r = client.post(f"/api/models/{material_id}/inpaint", files={**files, "seed": (None, "4")})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["size"] == [SIZE, SIZE] and [m["name"] for m in body["maps"]] == ["albedo", "normal", "height"]
    got = {m["name"]: decode(m["png"]) for m in body["maps"]}
    np.testing.assert_array_equal(got["albedo"][~hole], albedo[~hole])
    assert not np.array_equal(got["albedo"][hole], albedo[hole])
    path = tmp_path / "m.npz"
    path.write_bytes(client.get(f"/api/models/{material_id}/file").content)
    from tghop.imageio import load_image

    read = {}
    for name, (_, content) in [("normal", files["map:normal"]), ("height", files["map:height"])]:
        (tmp_path / f"{name}.png").write_bytes(content)
        read[name] = load_image(tmp_path / f"{name}.png", dtype=None)
    rng = np.random.default_rng(4)  # seed 4's generator: its first fill is seed 4's
    want = inpaint_material(load_model(path, material=True), {"albedo": albedo, **read}, hole, rng=rng)
    np.testing.assert_array_equal(got["albedo"], want["albedo"])
    np.testing.assert_array_equal(got["normal"], to_uint16(want["normal"]))
    # fill 2 (0.61): the second drawn from seed 4's generator, as tghop inpaint --maps --seed 4 --count 2 draws it
    second = inpaint_material(load_model(path, material=True), {"albedo": albedo, **read}, hole, rng=rng)
    r = client.post(f"/api/models/{material_id}/inpaint", files={**files, "seed": (None, "4"), "fill": (None, "2")})
    assert r.status_code == 200 and r.headers["x-tghop-fill"] == "2", r.text
    got = {m["name"]: decode(m["png"]) for m in r.json()["maps"]}
    np.testing.assert_array_equal(got["albedo"], second["albedo"])
    np.testing.assert_array_equal(got["normal"], to_uint16(second["normal"]))
    # Grown (extend): the picture kept at its anchor in every map, as multipart to the page
    r = client.post(f"/api/models/{material_id}/extend", headers={"Accept": "multipart/form-data"}, files={
        "image": files["image"], "map:normal": files["map:normal"], "map:height": files["map:height"],
        "size": (None, f"{SIZE}x{SIZE + 32}"), "anchor": (None, "left"), "seed": (None, "2")})
    assert r.status_code == 200 and r.headers["content-type"].startswith("multipart/form-data"), r.text
    parts = multipart_parts(r)
    assert list(parts) == ["_meta", "albedo", "normal", "height"]
    (tmp_path / "grown.png").write_bytes(parts["albedo"][1])
    grown = load_image(tmp_path / "grown.png", dtype=None)
    assert grown.shape == (SIZE, SIZE + 32, 3)
    np.testing.assert_array_equal(grown[:, :SIZE], albedo)
    # A map of another size than the picture is refused, though grown it would be of the new size
    r = client.post(f"/api/models/{material_id}/extend", files={
        "image": files["image"], "map:normal": ("n.png", png(to_uint16(maps["normal"][:, :SIZE - 8]))),
        "map:height": files["map:height"], "size": (None, f"{SIZE}x{SIZE + 32}"), "anchor": (None, "left")})
    assert_error(r, 400, f"the map normal (n.png) is {SIZE}x{SIZE - 8} but the picture is {SIZE}x{SIZE}")
    # A map whose alpha holds data is refused, as a fit's (it was dropped as transparency)
    see_through = np.dstack([to_uint8(maps["height"][..., 0]), np.full((SIZE, SIZE), 9, np.uint8)])
    r = client.post(f"/api/models/{material_id}/extend", files={
        "image": files["image"], "map:normal": files["map:normal"], "map:height": ("h.png", png(see_through)),
        "size": (None, f"{SIZE}x{SIZE + 32}"), "anchor": (None, "left")})
    assert_error(r, 400, "(h.png) has an alpha channel that holds data")


def test_a_materials_fill_keeps_each_files_depth_as_a_textures_does(client, material_id):
    # The material's albedo and height are 8-bit; sent at 16 bits they come back at 16 (the texture
    # path keeps a 16-bit picture's depth; tghop inpaint --maps writes each map at its file's)
    albedo = to_uint16(data.bricks(SIZE, rng=8)) ^ np.uint16(5)  # low bits an 8-bit answer would lose
    maps = example_maps(data.bricks(SIZE, rng=8))
    hole = np.zeros((SIZE, SIZE), dtype=bool)
    hole[30:60, 20:70] = True
    r = client.post(f"/api/models/{material_id}/inpaint", files={
        "image": ("p.png", png(albedo)), "mask": ("m.png", png(hole.astype(np.uint8) * 255)),
        "map:normal": ("n.png", png(to_uint8(maps["normal"]))), "map:height": ("h.png", png(to_uint16(maps["height"]))),
        "seed": (None, "4")})
    assert r.status_code == 200, r.text
    body = r.json()
    assert [(m["name"], m["depth"]) for m in body["maps"]] == [("albedo", 16), ("normal", 8), ("height", 16)]
    got = {m["name"]: decode(m["png"]) for m in body["maps"]}
    assert got["albedo"].dtype == np.uint16 and got["normal"].dtype == np.uint8
    np.testing.assert_array_equal(got["albedo"][~hole], albedo[~hole])
    np.testing.assert_array_equal(got["height"][~hole], to_uint16(maps["height"])[~hole])


def test_a_materials_fill_may_send_as_much_as_its_fit_but_no_file_over_one_files_limit(client, material_id):
    # The picture and two maps of 30 MB each (no images: 400 naming one), over 50 MB together: not 413
    picture = png(to_uint8(data.bricks(48)))
    files = {"image": ("p.png", picture), "size": (None, "64x64"),
             "map:normal": ("n.png", b"\0" * (30 << 20)), "map:height": ("h.png", b"\0" * (30 << 20))}
    assert_error(client.post(f"/api/models/{material_id}/extend", files=files), 400, "n.png")
    files["map:normal"] = ("n.png", b"\0" * ((50 << 20) + 10))
    assert_error(client.post(f"/api/models/{material_id}/extend", files=files), 413,
                 "n.png is over the limit of 50 MB a file")


def test_a_materials_maps_say_the_suffix_of_their_files_as_tghop_synth_names_them():
    # The page named its downloads <result>_<map name>.png: Rock023_2K_NormalGL kept the source's name and 2K
    from types import SimpleNamespace

    from tghop.server.materials import encode_maps

    names = ["albedo", "Rock023_2K_NormalGL", "Rock023_2K_Roughness"]
    material = SimpleNamespace(names_=names, depths_=[8, 16, 8], normal_=[False, True, False])
    maps = {name: np.full((4, 5, 1 if "Rough" in name else 3), 0.5) for name in names}
    assert [m["suffix"] for m in encode_maps(maps, material)] == [None, "NormalGL", "Roughness"]


def test_a_materials_maps_are_read_as_data_in_a_fit_and_a_fill(client, material_id):
    # 0.57: a normal map with a linear gAMA chunk was converted as colours: its fit refused ("not unit vectors"),
    # its fill's known pixels changed
    from test_profiles import linear_png

    maps = example_maps(data.bricks(SIZE, rng=3))
    normal, height = to_uint8(maps["normal"]), to_uint8(maps["height"][..., 0])
    fit(client, {**albedo_file(), "map:normal": ("bricks_normal.png", linear_png(normal)),
                 "map:height": ("height.png", linear_png(height))})
    hole = np.zeros((SIZE, SIZE), dtype=bool)
    hole[30:60, 20:70] = True
    picture, mask = png(to_uint8(data.bricks(SIZE, rng=3))), png(hole.astype(np.uint8) * 255)
    r = client.post(f"/api/models/{material_id}/inpaint", files={
        "image": ("p.png", picture), "mask": ("m.png", mask),
        "map:normal": ("n.png", linear_png(normal)), "map:height": ("h.png", linear_png(height)), "seed": (None, "4")})
    assert r.status_code == 200, r.text
    got = {m["name"]: decode(m["png"]) for m in r.json()["maps"]}
    np.testing.assert_array_equal(got["normal"][~hole], normal[~hole])
    np.testing.assert_array_equal(got["height"][~hole][..., 0], height[~hole])


def test_a_fits_warnings_are_told_with_the_models_summary(client):
    # what Material.fit warns of (a map named as a height map that holds a colour image) went to the server's
    # console (0.57); 0.58: the model's summary says it, which the page shows when the fit is done
    image = to_uint8(data.bricks(SIZE, rng=7))
    model = fit(client, {"image": ("Rock_Color.png", png(image)), "map:Rock_Height": ("h.png", png(image))})
    notes = client.get(f"/api/models/{model}").json()["notes"]
    assert [n for n in notes if "named as a height map" in n and "colour image" in n], notes
