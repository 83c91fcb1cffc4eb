"""Progress bars on a terminal, silence elsewhere."""

from __future__ import annotations

import io
import sys

from locoman.progress import progress


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_off_a_terminal_the_items_pass_through_silently(capsys):
    assert list(progress(range(5), "generate tiny")) == [0, 1, 2, 3, 4]
    assert capsys.readouterr().err == ""


def test_on_a_terminal_a_bar_names_the_step(monkeypatch):
    terminal = Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    assert list(progress(iter("abc"), "retarget s1_basket", total=3)) == ["a", "b", "c"]
    assert "retarget s1_basket" in terminal.getvalue() and "/3" in terminal.getvalue()
