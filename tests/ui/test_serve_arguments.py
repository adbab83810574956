"""``handover serve`` refuses an impossible port or an address this computer does not have on its
command line, before anything starts; port 0 binds any free port and prints the one bound."""

from __future__ import annotations

import pytest
from support.browser import serve

from app.cli import main


@pytest.mark.parametrize("port", ["70000", "65536", "-1", "http"])
def test_a_port_outside_1_to_65535_is_refused_with_its_range(tmp_path, capsys, port):
    with pytest.raises(SystemExit) as exited:
        main(["serve", "--study", str(tmp_path / "study"), "--tablet-port", port])
    assert exited.value.code == 2
    assert (f"argument --tablet-port: port = '{port}' must be a whole number in [1, 65535], or 0 "
            "for any free port") in capsys.readouterr().err
    assert not (tmp_path / "study").exists()


@pytest.mark.parametrize(("host", "message"), [
    ("192.0.2.1", "host = '192.0.2.1': this computer cannot serve on that address (Cannot assign "
                  "requested address)"),  # TEST-NET-1: no computer has it
    ("127.0.0.999", "host = '127.0.0.999' is not an IP address"),
    ("tablet.local", "host = 'tablet.local' is not an IP address"),
])
def test_an_address_this_computer_lacks_is_refused_at_once(tmp_path, capsys, host, message):
    """Before, ``serve --host`` with an address that is not this computer's hung without a word."""
    with pytest.raises(SystemExit) as exited:
        main(["serve", "--study", str(tmp_path / "study"), "--host", host])
    assert exited.value.code == 2
    assert f"argument --host: {message}" in capsys.readouterr().err
    assert not (tmp_path / "study").exists()


def test_port_0_binds_a_free_port_each_and_prints_the_urls(tmp_path):
    """Two servers at once on port 0: four different ports, each the one printed and bound."""
    with serve(tmp_path / "a") as first, serve(tmp_path / "b") as second:
        urls = [first.tablet_url, first.dashboard_url, second.tablet_url, second.dashboard_url]
        ports = [int(url.rsplit(":", 1)[1]) for url in urls]
        assert 0 not in ports and len(set(ports)) == 4, urls
        first.shutdown()
        second.shutdown()


def test_blind_is_the_default_and_unblind_is_asked_for(capsys):
    """``--blind`` stays accepted (it is the default); ``--unblind`` with it is refused."""
    from app.cli import build_parser

    parser = build_parser()
    assert not parser.parse_args(["serve"]).unblind
    assert not parser.parse_args(["serve", "--blind"]).unblind
    assert parser.parse_args(["serve", "--unblind"]).unblind
    with pytest.raises(SystemExit) as exited:
        parser.parse_args(["serve", "--blind", "--unblind"])
    assert exited.value.code == 2
    assert "argument --unblind: not allowed with argument --blind" in capsys.readouterr().err
    serve = parser._subparsers._group_actions[0].choices["serve"]
    [blind] = [action for action in serve._actions if "--blind" in action.option_strings]
    assert blind.help.startswith("the default:")
