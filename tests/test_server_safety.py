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
