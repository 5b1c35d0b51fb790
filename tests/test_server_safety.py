"""``tghop serve`` keeps to its own users: a request naming another server in its Host (DNS
rebinding) or coming from a page of another site (its Origin) is refused with 403 and one line,
before its body is read (:mod:`tghop.server.safety`)."""

import pytest

httpx = pytest.importorskip("httpx", reason="the server's tests need httpx: pip install -e '.[test,web,web-test]'")
pytest.importorskip("uvicorn", reason="the web extra is not installed: pip install -e '.[web]'")

from conftest import LiveServer  # noqa: E402


@pytest.fixture(scope="module")
def client(live_server):
    with httpx.Client(base_url=live_server.url, timeout=60) as c:
        yield c


def refused(response, *fragments):
    assert response.status_code == 403, response.text
    message = response.json()["error"]
    assert message.startswith("refused: ") and "\n" not in message
    for fragment in fragments:
        assert fragment in message, message
    return message


@pytest.mark.parametrize("host", ["evil.example:8000", "evil.example", "127.0.0.1.evil.example", "10.0.0.7:80",
                                  "localhost.evil.example"])
def test_a_host_of_another_name_is_refused(client, host):
    port = client.base_url.port
    refused(client.get("/api", headers={"host": host}), repr(host), f"http://127.0.0.1:{port}/")
    refused(client.get("/", headers={"host": host}))
    refused(client.post("/api/models", files={"builtin": (None, "bricks")}, headers={"host": host}))


@pytest.mark.parametrize("host", ["127.0.0.1", "localhost", "LOCALHOST", "localhost.", "[::1]"])
def test_the_loopback_names_are_served(client, host):
    port = client.base_url.port
    for value in (host, f"{host}:{port}"):
        r = client.get("/api", headers={"host": value})
        assert r.status_code == 200 and "builtins" in r.json()


@pytest.mark.parametrize("origin", ["http://evil.example", "null", "http://127.0.0.1:1", "http://localhost:{port}"])
def test_a_page_of_another_site_is_refused(client, origin):
    """A page elsewhere posts a form (a "simple" request, no preflight) to the server: refused before
    any work (no fit starts, no body is read)."""
    origin = origin.format(port=client.base_url.port)  # localhost is another origin than 127.0.0.1
    message = refused(client.post("/api/models", files={"builtin": (None, "bricks")}, headers={"origin": origin}),
                      repr(origin))
    assert "only its own page" in message
    refused(client.post("/api/models/upload", content=b"x" * 1000, headers={"origin": origin}))
    refused(client.delete("/api/jobs/" + "0" * 32, headers={"origin": origin}))
    refused(client.get("/api", headers={"origin": origin}))


def test_the_page_itself_is_served(client):
    """The page's requests are same-origin: the Origin is the server's own (or there is none)."""
    url = str(client.base_url).rstrip("/")
    assert client.get("/api", headers={"origin": url}).status_code == 200
    assert client.get("/api", headers={"origin": url + "/"}).status_code == 200
    host = f"localhost:{client.base_url.port}"
    assert client.get("/api", headers={"origin": f"http://{host}", "host": host}).status_code == 200
    r = client.post("/api/models", files={"builtin": (None, "nothing")}, headers={"origin": url})
    assert r.status_code == 400 and "nothing" in r.json()["error"]  # the route's own answer
    assert client.get("/").status_code == 200


def test_the_names_a_server_answers_to():
    from tghop.server.safety import allowed_hosts

    assert allowed_hosts("127.0.0.1") == {"127.0.0.1", "localhost", "::1"}
    assert allowed_hosts("::1") == {"127.0.0.1", "localhost", "::1"}
    assert allowed_hosts("192.168.1.5") == {"127.0.0.1", "localhost", "::1", "192.168.1.5"}
    assert allowed_hosts("Studio.Local") == {"127.0.0.1", "localhost", "::1", "studio.local"}
    for every in ("0.0.0.0", "::", ""):  # every interface: any name reaches it, none is refused
        assert allowed_hosts(every) is None


def test_a_server_given_another_host_answers_to_it_and_every_interface_to_any(tmp_path):
    named = LiveServer(tmp_path / "a", host="studio.local")
    try:
        with httpx.Client(base_url=named.url, timeout=60) as c:
            assert c.get("/api", headers={"host": "studio.local:8000"}).status_code == 200
            refused(c.get("/api", headers={"host": "other.local"}), "studio.local")
    finally:
        named.stop()
    anywhere = LiveServer(tmp_path / "b", host="0.0.0.0")
    try:
        with httpx.Client(base_url=anywhere.url, timeout=60) as c:
            assert c.get("/api", headers={"host": "any.name.example"}).status_code == 200
            refused(c.post("/api/models", headers={"host": "any.name.example", "origin": "http://evil.example"}))
    finally:
        anywhere.stop()


def zip_bomb(unpacked: int, name: str = "big.npy") -> bytes:
    """A ZIP archive of one deflated member of ``unpacked`` zero bytes (an .npy header first): about
    a thousandth of that size."""
    import io
    import zipfile

    from numpy.lib import format as npy

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as archive, archive.open(name, "w", force_zip64=True) as fh:
        npy.write_array_header_1_0(fh, {"descr": "|u1", "fortran_order": False, "shape": (unpacked,)})
        chunk, left = bytes(1 << 24), unpacked
        while left:
            fh.write(chunk[:left])
            left -= min(left, len(chunk))
    return buf.getvalue()


def test_a_model_file_that_unpacks_to_too_much_is_refused_before_it_is_read(client, live_server):
    """A 210 MB array deflated into a 200 KB .npz: refused from the sizes the archive declares,
    before NumPy unpacks it (50 MB of it would unpack to 50 GB)."""
    import os

    from tghop.server.safety import MAX_UNPACKED_BYTES

    bomb = zip_bomb(MAX_UNPACKED_BYTES + 10 * 1024**2)
    assert len(bomb) < 1024**2
    for r in (client.post("/api/models/upload", content=bomb, headers={"content-type": "application/octet-stream"}),
              client.post("/api/models/upload", files={"model": ("bomb.npz", bomb)})):
        assert r.status_code == 400, r.text
        message = r.json()["error"]
        assert "unpacks to 210 MB, more than the 200 MB a model may hold" in message and "\n" not in message
    assert "bomb.npz unpacks" in message
    assert not [f for f in os.listdir(live_server.cache / "models") if f.endswith(".tmp")]  # nothing was written


def test_an_archive_of_too_many_members_is_refused(client):
    import io
    import zipfile

    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as archive:
        for i in range(5000):
            archive.writestr(f"a{i}.npy", b"")
    r = client.post("/api/models/upload", files={"model": ("many.npz", buf.getvalue())})
    assert r.status_code == 400, r.text
    assert r.json()["error"] == ("many.npz is a zip archive of 5,000 members (a model file or checkpoint has at most "
                                 "4,096), not a model; send a model tghop wrote")
    buf = io.BytesIO()  # few members of long names: the directory's size says it (0.58 let it through to NumPy)
    with zipfile.ZipFile(buf, "w") as archive:
        for i in range(90):
            archive.writestr(f"{i:02d}" + "x" * 60_000, b"")
    r = client.post("/api/models/upload", files={"model": ("long.npz", buf.getvalue())})
    assert r.status_code == 400, r.text
    assert r.json()["error"].startswith("long.npz is a zip archive whose directory takes 5 MB (a model file's or "
                                        "checkpoint's takes at most 4 MB), not a model"), r.text


def test_a_checkpoint_that_unpacks_to_too_much_is_refused(client):
    pytest.importorskip("torch", reason="the co-occurrence routes need PyTorch")
    bomb = zip_bomb(300 * 1024**2, "archive/data/0")
    r = client.post("/api/cooc", files={"checkpoint": ("bomb.pt", bomb)})
    assert r.status_code == 400, r.text
    assert "bomb.pt unpacks to 300 MB, more than the 200 MB a co-occurrence checkpoint may hold" in r.json()["error"]


def test_malformed_requests_leave_the_terminal_quiet(tmp_path):
    """``tghop serve``'s terminal shows its address and, at Ctrl-C, one line: a malformed body
    (python-multipart logs a warning of its own for some) is the client's 400, not a line there."""
    import signal
    import subprocess
    import sys

    p = subprocess.Popen([sys.executable, "-m", "tghop", "serve", "--port", "0", "--cache", str(tmp_path / "cache")],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = p.stdout.readline().split()[3] + "api/models"
        bodies = [b"nothing", b"--xx\r\nContent-Disposition: form-data; name=\"builtin\"\r\n\r\nbricks",
                  b"--xx\r\nContent-Disposition: form-data\r\n\r\nbricks\r\n--xx--\r\n", b"--xy\r\n\r\n--xx--",
                  b"--xx\r\nContent-Disposition: form-data; name=\"\xff\"\r\n\r\n\xff\r\n--xx--\r\n"]
        for body in bodies:
            r = httpx.post(url, content=body, headers={"content-type": "multipart/form-data; boundary=xx"}, timeout=30)
            assert r.status_code == 400 and "\n" not in r.json()["error"], r.text
        assert httpx.post(url, content=b"x", headers={"content-type": "multipart/form-data"}).status_code == 400
        assert httpx.get(url, headers={"host": "evil.example"}).status_code == 403
    finally:
        p.send_signal(signal.SIGINT)
        try:
            out, err = p.communicate(timeout=60)
        finally:
            if p.poll() is None:
                p.kill()
    assert err.strip().splitlines() == ["tghop server stopped"], err


@pytest.mark.parametrize("route", ["/api/models", "/api/models/upload", "/api/models/{id}/inpaint"])
def test_a_form_cut_short_says_so(client, route):
    """A multipart body without its closing boundary (cut short, or empty): the parser dropped the
    last part without a word, and the route said a field was missing ("no exemplar")."""
    route = route.format(id="0" * 64)
    head = b"--xx\r\nContent-Disposition: form-data; name=\"image\"; filename=\"a.png\"\r\n\r\n\x89PNG"
    kind = {"content-type": "multipart/form-data; boundary=xx"}
    for body in (head, b"", b"--xx\r\nContent-Disposition: form-data; name=\"builtin\"\r\n\r\nbricks"):
        r = client.post(route, content=body, headers=kind)
        assert r.status_code == 400, r.text
        assert r.json()["error"] == (f"malformed multipart request (no closing boundary --xx--: the body of "
                                     f"{len(body):,} bytes is empty or cut short); send the whole form"), r.text
    quoted = {"content-type": 'multipart/form-data; boundary="x;y"'}
    whole = b"--x;y\r\nContent-Disposition: form-data; name=\"builtin\"\r\n\r\nnone\r\n--x;y--\r\n"
    r = client.post("/api/models", content=whole, headers=quoted)
    assert r.status_code == 400 and "unknown built-in exemplar 'none'" in r.json()["error"], r.text


def test_a_method_a_route_does_not_take_says_which_it_does(client):
    for method, path, allow in [("GET", "/api/models", "POST"), ("PUT", "/api/models/upload", "POST"),
                                ("OPTIONS", "/api/images/guided", "POST"), ("POST", "/api", "GET, HEAD")]:
        r = client.request(method, path)
        assert r.status_code == 405, r.text
        assert r.json()["error"] == f"{method} is not allowed at {path}; use {allow} (docs/serve.md)"
        assert r.headers["allow"] == allow
    r = client.get("/api/nothing")
    assert r.status_code == 404 and r.json()["error"].startswith("nothing at /api/nothing; the API is under /api")
