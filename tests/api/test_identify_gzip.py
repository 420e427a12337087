"""Gzip-compressed telemetry: a gzip file upload (known by its magic bytes) and a JSON body
sent with ``Content-Encoding: gzip`` give the plain file's verdict; a decompression bomb
is refused after inflating no more than the body's limit, a corrupt or truncated gzip is a
422 naming the file, and a coding the API does not read is a 415 naming it."""

from __future__ import annotations

import gzip
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from inertia_id import InertiaClassifier, Scenario, SimulationResult, simulate

from .support import GOOD_SEQUENCE, Api
from .test_identify import csv_text, telemetry


@pytest.fixture(scope="module")
def flight(paper: Scenario) -> SimulationResult:
    return simulate(paper, GOOD_SEQUENCE, 1, np.random.default_rng(7))


@pytest.fixture
def classifier_id(api: Api, classifier: InertiaClassifier) -> str:
    return api.insert_classifier(api.create_scenario()["id"], classifier)


def _upload(api: Api, path: str, classifier_id: str, name: str, content: bytes) -> Any:
    return api.post(path, data={"classifier_id": classifier_id}, files={"file": (name, content)})


def _gzip_json_body(api: Api, path: str, body: bytes, encoding: str = "gzip") -> Any:
    headers = {**api.auth, "content-type": "application/json", "content-encoding": encoding}
    return api.client.post(path, content=body, headers=headers)


def test_gzip_csv_and_json_give_the_plain_files_verdict(
    api: Api, classifier_id: str, flight: SimulationResult, paper: Scenario
) -> None:
    k = 3
    text = csv_text(flight.time_s, flight.omega_measured[k, 0]).encode()
    plain = _upload(api, "/identify", classifier_id, "pass.csv", text)
    assert plain.status_code == 200, plain.text
    expected = plain.json()
    assert expected["candidate"] == paper.candidate_names[k]
    document = json.dumps(telemetry(flight, k)).encode()
    uploads = {
        "pass.csv.gz": gzip.compress(text),
        # Known by its magic bytes, not its name.
        "pass.csv": gzip.compress(text),
        "downlink-0042": gzip.compress(text),
        "pass.json.gz": gzip.compress(document),
    }
    for name, content in uploads.items():
        response = _upload(api, "/identify", classifier_id, name, content)
        assert response.status_code == 200, (name, response.text)
        assert response.json()["candidate"] == expected["candidate"], name
        assert response.json()["distances"] == pytest.approx(expected["distances"]), name
    body = {"classifier_id": classifier_id, "telemetry": telemetry(flight, k)}
    as_json = api.post("/identify", json=body)
    assert as_json.status_code == 200, as_json.text
    encoded = _gzip_json_body(api, "/identify", gzip.compress(json.dumps(body).encode()))
    assert encoded.status_code == 200, encoded.text
    assert encoded.json() == as_json.json()
    assert as_json.json()["distances"] == pytest.approx(expected["distances"])
    # "identity" is no coding at all; x-gzip is gzip's old name.
    same = _gzip_json_body(api, "/identify", json.dumps(body).encode(), encoding="identity")
    assert same.json() == as_json.json()
    old_name = _gzip_json_body(
        api, "/identify", gzip.compress(json.dumps(body).encode()), encoding="x-gzip"
    )
    assert old_name.json() == as_json.json()


def test_identify_partial_reads_gzip_as_identify_does(
    api: Api, classifier_id: str, flight: SimulationResult
) -> None:
    """The clustering answers no posterior over time: the gzip upload and body reach
    that refusal as the plain ones do (before, gzip was "not UTF-8 text")."""
    text = csv_text(flight.time_s[:30], flight.omega_measured[0, 0][:30]).encode()
    body = {"classifier_id": classifier_id, "telemetry": telemetry(flight, 0)}
    answers = [
        _upload(api, "/identify/partial", classifier_id, "pass.csv", text),
        _upload(api, "/identify/partial", classifier_id, "pass.csv.gz", gzip.compress(text)),
        _gzip_json_body(api, "/identify/partial", gzip.compress(json.dumps(body).encode())),
    ]
    for response in answers:
        assert response.status_code == 422 and "partial series" in response.text, response.text


def test_a_gzip_bomb_is_refused_at_the_bodys_limit(
    api: Api, classifier_id: str, gzip_bomb: Path
) -> None:
    """1 GiB of zeros in 1 MB of gzip passes the body's limit compressed; decompressed it
    is refused 413 naming the limit, after inflating no more than the limit (the process
    grew by tens of MB, not a gigabyte: measured by hand, see the change's report)."""
    bomb = gzip_bomb.read_bytes()
    limit = api.settings.max_body_bytes
    assert len(bomb) < limit
    refusal = f"decompressed size exceeds the limit of {limit} bytes"
    for path in ("/identify", "/identify/partial"):
        response = _upload(api, path, classifier_id, "pass.csv.gz", bomb)
        assert response.status_code == 413, response.text
        detail = response.json()["detail"]
        assert "telemetry file 'pass.csv.gz'" in detail and refusal in detail
        assert "INERTIA_ID_MAX_BODY_BYTES" in detail
        response = _gzip_json_body(api, path, bomb)
        assert response.status_code == 413, response.text
        assert "request body (Content-Encoding: gzip)" in response.json()["detail"]
        assert refusal in response.json()["detail"]


def test_a_gzip_just_within_the_limit_is_read(api: Api, classifier_id: str) -> None:
    """The limit is on what the gzip holds: limit bytes are read (and judged as
    telemetry), limit + 1 refused."""
    limit = api.settings.max_body_bytes
    header = b"time_s,wx,wy,wz\n"
    at_limit = header + b" " * (limit - len(header))
    read = _upload(api, "/identify", classifier_id, "pass.csv.gz", gzip.compress(at_limit))
    assert read.status_code == 422, read.text
    assert "at least 2 samples" in read.text
    over = _upload(api, "/identify", classifier_id, "pass.csv.gz", gzip.compress(at_limit + b" "))
    assert over.status_code == 413, over.text


def test_a_truncated_or_corrupt_gzip_is_a_422_naming_the_file(
    api: Api, classifier_id: str, flight: SimulationResult
) -> None:
    text = csv_text(flight.time_s, flight.omega_measured[1, 0]).encode()
    compressed = gzip.compress(text)
    corrupt = bytearray(compressed)
    corrupt[len(corrupt) // 2] ^= 0xFF
    cases = {
        "truncated": (compressed[: len(compressed) // 2], "Compressed file ended before"),
        "corrupt": (bytes(corrupt), "is not a valid gzip stream"),
        "trailing bytes": (compressed + b"not gzip", "Not a gzipped file"),
    }
    for case, (content, reason) in cases.items():
        response = _upload(api, "/identify", classifier_id, "pass.csv.gz", content)
        assert response.status_code == 422, (case, response.text)
        error = response.json()["detail"][0]
        assert error["loc"] == ["body", "file"], case
        assert "telemetry file 'pass.csv.gz' is not a valid gzip stream" in error["msg"], case
        assert reason in error["msg"], case
    body = gzip.compress(b'{"classifier_id": "x"}')[:-6]
    response = _gzip_json_body(api, "/identify", body)
    assert response.status_code == 422, response.text
    assert "request body (Content-Encoding: gzip) is not a valid gzip stream" in response.text


def test_gzip_inside_gzip_is_a_422_saying_it_is_compressed_twice(
    api: Api, classifier_id: str, flight: SimulationResult
) -> None:
    """A .gz compressed again was refused as "not UTF-8 text ... byte 0x8b", naming
    neither the file nor why; it names both, for a file part and a JSON body."""
    text = csv_text(flight.time_s, flight.omega_measured[1, 0]).encode()
    twice = gzip.compress(gzip.compress(text))
    response = _upload(api, "/identify", classifier_id, "pass.csv.gz", twice)
    assert response.status_code == 422, response.text
    error = response.json()["detail"][0]
    assert error["loc"] == ["body", "file"]
    assert error["msg"].startswith("telemetry file 'pass.csv.gz' is gzip holding gzip again")
    body = json.dumps({"classifier_id": classifier_id, "telemetry": telemetry(flight, 0)})
    response = _gzip_json_body(api, "/identify", gzip.compress(gzip.compress(body.encode())))
    assert response.status_code == 422, response.text
    assert "request body (Content-Encoding: gzip) is gzip holding gzip again" in response.text


def test_a_coding_the_api_does_not_read_is_a_415_naming_it(
    api: Api, classifier_id: str, flight: SimulationResult
) -> None:
    """Before, the header was ignored: a brotli body was refused as malformed JSON, and
    a plain one labelled br was judged."""
    body = json.dumps({"classifier_id": classifier_id, "telemetry": telemetry(flight, 0)})
    for encoding in ("br", "deflate", "gzip, br", "zstd"):
        response = _gzip_json_body(api, "/identify", body.encode(), encoding=encoding)
        assert response.status_code == 415, (encoding, response.text)
        assert f"Content-Encoding {encoding!r} is not supported" in response.json()["detail"]
    # A form is read as sent: gzip its telemetry file, not the form.
    form = api.client.post(
        "/identify",
        data={"classifier_id": classifier_id},
        files={"file": ("pass.csv", b"time_s,wx,wy,wz\n")},
        headers={**api.auth, "content-encoding": "gzip"},
    )
    assert form.status_code == 415, form.text
    assert "gzip is read for a JSON body only" in form.json()["detail"]


def test_a_coded_body_on_another_route_is_a_415_not_read_as_plain(api: Api) -> None:
    """Other routes ignored Content-Encoding: a gzip scenario was "not acceptable JSON:
    'utf-8' codec can't decode byte 0x8b", and a plain body labelled gzip or br was
    stored. Only /identify and /identify/partial read gzip; elsewhere a coded JSON body
    is a 415 naming the coding, and nothing is stored."""
    scenario = api.create_scenario()
    plain = json.dumps({"preset": "paper"}).encode()
    sequence = json.dumps({"sequence": [[4, 4, 4, 0, 0, 0]]}).encode()
    for path, body in (
        ("/scenarios", plain),
        ("/jobs", json.dumps({"type": "train", "scenario_id": scenario["id"]}).encode()),
        (f"/scenarios/{scenario['id']}/plan", sequence),
    ):
        for encoding, content in (("gzip", gzip.compress(body)), ("gzip", body), ("br", body)):
            response = _gzip_json_body(api, path, content, encoding=encoding)
            assert response.status_code == 415, (path, encoding, response.text)
            detail = response.json()["detail"]
            assert f"Content-Encoding {encoding!r} is not supported on this route" in detail
    assert [s["id"] for s in api.get("/scenarios").json()["items"]] == [scenario["id"]]
    # Without the key, still a 401 before the body (or its coding) is looked at.
    bare = {"content-type": "application/json", "content-encoding": "br"}
    assert api.client.post("/scenarios", content=plain, headers=bare).status_code == 401
    # Plain (or identity) as before.
    response = _gzip_json_body(api, "/scenarios", plain, encoding="identity")
    assert response.status_code == 201, response.text


def test_a_json_body_sent_as_another_media_type_is_a_415_naming_it(api: Api) -> None:
    """``curl -d '{"preset": "paper"}'`` sends application/x-www-form-urlencoded; FastAPI
    gave such a body to the model as bytes, a 422 "Input should be a valid dictionary or
    object to extract fields from" that named neither the header nor the fix."""
    scenario = api.create_scenario()
    plain = json.dumps({"preset": "paper"}).encode()
    job = json.dumps({"type": "train", "scenario_id": scenario["id"]}).encode()
    for path, body in (("/scenarios", plain), ("/jobs", job)):
        for media in ("application/x-www-form-urlencoded", "text/plain"):
            headers = {**api.auth, "content-type": media}
            response = api.client.post(path, content=body, headers=headers)
            assert response.status_code == 415, (path, media, response.text)
            detail = response.json()["detail"]
            assert f"not {media!r}" in detail and "application/json" in detail
    assert [s["id"] for s in api.get("/scenarios").json()["items"]] == [scenario["id"]]
    untyped = api.client.post("/scenarios", content=plain, headers=api.auth)
    assert untyped.status_code == 415 and "with no type" in untyped.json()["detail"]
    # JSON under its own names is read as before.
    for media in ("application/json", "application/json; charset=utf-8"):
        headers = {**api.auth, "content-type": media}
        response = api.client.post("/scenarios", content=plain, headers=headers)
        assert response.status_code == 201, (media, response.text)
    # Without the key, still a 401 before the body (or its type) is looked at.
    bare = {"content-type": "text/plain"}
    assert api.client.post("/scenarios", content=plain, headers=bare).status_code == 401


def test_a_json_body_in_a_charset_other_than_utf8_is_a_415_naming_it(
    api: Api, classifier_id: str, flight: SimulationResult
) -> None:
    """``application/json; charset=latin-1`` was accepted and its body read as UTF-8: the
    name ``Ã©nergie`` sent in Latin-1 (bytes C3 A9) was stored as ``énergie``, and
    ``Énergie`` (byte C9) was a 422 about the 'utf-8' codec. JSON between systems must be
    UTF-8 (RFC 8259, 8.1): another charset is refused by name, nothing stored."""
    stored = [s["id"] for s in api.get("/scenarios").json()["items"]]
    overrides = {"name": "Ã©nergie"}
    misread = json.dumps({"preset": "paper", "overrides": overrides}, ensure_ascii=False)
    assert b"\xc3\xa9" in misread.encode("latin-1")
    identify = json.dumps({"classifier_id": classifier_id, "telemetry": telemetry(flight, 3)})
    for path, text in (("/scenarios", misread), ("/identify", identify)):
        for charset in ("latin-1", "ISO-8859-1", '"windows-1252"', "utf-16", "no-such"):
            headers = {**api.auth, "content-type": f"application/json; charset={charset}"}
            response = api.client.post(path, content=text.encode("latin-1"), headers=headers)
            assert response.status_code == 415, (path, charset, response.text)
            detail = response.json()["detail"]
            named = charset.strip('"').lower()
            assert detail.startswith(f"charset {named!r} is not supported"), detail
            assert "UTF-8" in detail
    assert [s["id"] for s in api.get("/scenarios").json()["items"]] == stored
    # UTF-8 under any of its names, or none, is read as before.
    named = json.dumps({"preset": "paper", "overrides": {"name": "Énergie"}}).encode()
    for charset in ("", "; charset=utf-8", "; charset=UTF-8", '; charset="utf8"'):
        headers = {**api.auth, "content-type": f"application/json{charset}"}
        response = api.client.post("/scenarios", content=named, headers=headers)
        assert response.status_code == 201, (charset, response.text)
        assert response.json()["name"] == "Énergie"
    headers = {**api.auth, "content-type": "application/json; charset=utf-8"}
    verdict = api.client.post("/identify", content=identify.encode(), headers=headers)
    assert verdict.status_code == 200, verdict.text


def test_a_json_body_labelled_ascii_is_read_as_utf8(
    api: Api, classifier_id: str, flight: SimulationResult
) -> None:
    """``application/json; charset=us-ascii`` was a 415 "charset 'us-ascii' is not
    supported", though ASCII is a subset of UTF-8 (RFC 8259, 8.1): an ASCII body read as
    UTF-8 is read as sent. Both names, any case, quoted or not, on every route."""
    scenario = json.dumps({"preset": "paper", "overrides": {"name": "ascii"}}).encode("ascii")
    identify = json.dumps({"classifier_id": classifier_id, "telemetry": telemetry(flight, 3)})
    for charset in ("us-ascii", "US-ASCII", '"us-ascii"', "ascii", '"ASCII"'):
        headers = {**api.auth, "content-type": f"application/json; charset={charset}"}
        response = api.client.post("/scenarios", content=scenario, headers=headers)
        assert response.status_code == 201, (charset, response.text)
        assert response.json()["name"] == "ascii"
        verdict = api.client.post("/identify", content=identify.encode("ascii"), headers=headers)
        assert verdict.status_code == 200, (charset, verdict.text)
