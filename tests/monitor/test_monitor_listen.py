"""Where the monitor listens and who may read it: every refusal names the option and why, a
non-loopback address needs a token, the token is never shown."""

from __future__ import annotations

import pytest

from bench.monitor.listen import Listen, MonitorSettingsError, is_loopback, listen_settings, parse_address

TOKEN = "0123456789abcdef-lab"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("127.0.0.1:8080", ("127.0.0.1", 8080)),
        ("8080", ("127.0.0.1", 8080)),
        ("localhost:0", ("localhost", 0)),
        ("[::1]:9000", ("::1", 9000)),
        ("0.0.0.0:80", ("0.0.0.0", 80)),
    ],
)
def test_addresses_read(text: str, expected: tuple[str, int]) -> None:
    assert parse_address(text, "--monitor") == expected


@pytest.mark.parametrize(
    ("text", "said"),
    [
        ("127.0.0.1:http", "the port 'http' is not a number"),
        ("127.0.0.1:70000", "outside 0..65535"),
        (":8080", "no host before ':'"),
        ("::1:8080", "IPv6 address in brackets"),
    ],
)
def test_bad_addresses_refused(text: str, said: str) -> None:
    with pytest.raises(MonitorSettingsError, match=said) as refused:
        parse_address(text, "--monitor")
    assert str(refused.value).startswith(f"--monitor {text!r}")


@pytest.mark.parametrize("host", ["127.0.0.1", "127.3.2.1", "::1", "localhost"])
def test_loopback(host: str) -> None:
    assert is_loopback(host)


@pytest.mark.parametrize("host", ["0.0.0.0", "192.168.0.20", "::", "bench-pc.lab", "10.0.0.1"])
def test_not_loopback_needs_a_token(host: str) -> None:
    assert not is_loopback(host)
    address = f"[{host}]:8080" if ":" in host else f"{host}:8080"
    with pytest.raises(MonitorSettingsError, match=r"not a loopback address.*--monitor-token"):
        listen_settings(address, "--monitor")
    assert listen_settings(address, "--monitor", token=TOKEN).token == TOKEN


def test_token_rules(tmp_path) -> None:
    with pytest.raises(MonitorSettingsError, match="at least 16"):
        listen_settings("0.0.0.0:1", "--monitor", token="short")
    file = tmp_path / "token"
    file.write_text(f"  {TOKEN}  \nsecond line ignored\n")
    assert listen_settings("0.0.0.0:1", "--monitor", token_file=file).token == TOKEN
    with pytest.raises(MonitorSettingsError, match="not both"):
        listen_settings("0.0.0.0:1", "--monitor", token=TOKEN, token_file=file)
    with pytest.raises(MonitorSettingsError, match=r"--monitor-token-file .*missing: cannot be read"):
        listen_settings("0.0.0.0:1", "--monitor", token_file=tmp_path / "missing")
    (tmp_path / "empty").write_text("")
    with pytest.raises(MonitorSettingsError, match="has 0 characters"):
        listen_settings("0.0.0.0:1", "--monitor", token_file=tmp_path / "empty")


def test_the_token_is_compared_and_never_shown() -> None:
    listen = Listen("0.0.0.0", 1, TOKEN)
    assert listen.admits(TOKEN)
    assert not listen.admits(TOKEN[:-1]) and not listen.admits(None) and not listen.admits("")
    assert TOKEN not in repr(listen)
    assert Listen("127.0.0.1", 1).admits(None)
