"""Coactive hints in θ = (a, δ, k): which parameter each hint moves, and which way (eqs. (8)–(10)).

σ_j(d̃̇) = 1 / (1 + exp(−a (d̃̇ + δ))) (eq. 10) is large while the hand is not approaching, and
the coupling k σ_d σ_j (eqs. 8–9) then stretches time and brakes the robot: it waits. A larger δ
keeps σ_j large for longer as the hand approaches, so the robot holds back more and arrives later
("later": δ up; "sooner": δ down). The gain k scales how strongly the robot follows the hand at all
("react more to me": k up; "less": k down). The steepness a has no hint: no participant feels it
apart from δ.
"""

from __future__ import annotations

from app.learning.coactive import HintDirection
from session_store.vocabulary import Hint

#: hint → the parameter it moves and the sign (app.learning.coactive.hinted_theta moves it)
DIRECTIONS: dict[Hint, HintDirection] = {
    Hint.SOONER: HintDirection(parameter="delta", sign=-1),
    Hint.LATER: HintDirection(parameter="delta", sign=1),
    Hint.MORE: HintDirection(parameter="k", sign=1),
    Hint.LESS: HintDirection(parameter="k", sign=-1),
}
