"""``handover serve`` refuses an impossible port on its command line, before anything starts."""

from __future__ import annotations

import pytest

from app.cli import main


@pytest.mark.parametrize("port", ["70000", "0", "-1", "http"])
def test_a_port_outside_1_to_65535_is_refused_with_its_range(tmp_path, capsys, port):
    with pytest.raises(SystemExit) as exited:
        main(["serve", "--study", str(tmp_path / "study"), "--tablet-port", port])
    assert exited.value.code == 2
    assert f"argument --tablet-port: port = '{port}' must be a whole number in [1, 65535]" in \
        capsys.readouterr().err
    assert not (tmp_path / "study").exists()
