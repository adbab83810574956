"""Ties as information (``[learner] ties = "model"``): an "equal" placement in the likelihood.

The paper drops a placement on an earlier marker ("equal", Sect. III-C): it makes no comparison.
Yet "equal" says something: the two handovers felt alike, |u(θ_a) − u(θ_b)| is small. Here a tie
enters the likelihood of eq. (13) as two half comparisons, θ_a ≻ θ_b and θ_b ≻ θ_a, each with
weight ½:

    P(θ_a ~ θ_b) ∝ Φ(z)^½ · Φ(−z)^½,   z = (u(θ_a) − u(θ_b))/√2,

the geometric mean of the probabilities of the two orders under BoTorch's probit. It is largest at
u(θ_a) = u(θ_b) and falls off as the utilities part, so a tie pulls the two utilities together. It is
Davidson's tie model in probit form: R. R. Davidson, "On extending the Bradley–Terry model to
accommodate ties in paired comparison experiments", JASA 65(329):317–328, 1970, gives a tie the
probability ν·√(π_a π_b)/(π_a + π_b + ν√(π_a π_b)), i.e. proportional to the geometric mean of the
two Bradley–Terry win probabilities; the weights ½ are also the classical convention of scoring a
tie as half a win for each side. Being a product of probit terms, the Laplace approximation of
BoTorch's ``PairwiseGP`` handles it as is: each half is a row of the comparison matrix with its
weight (:class:`~app.learning.comparison_noise.BatchPositionProbit`).
"""

from __future__ import annotations

#: The weight of each half of a tie in the likelihood (a comparison weighs 1).
TIE_WEIGHT = 0.5


def tie_rows(a: int, b: int) -> list[tuple[tuple[int, int], float]]:
    """The two weighted comparison rows ``([winner, loser], weight)`` of a tie between points a, b."""
    return [((a, b), TIE_WEIGHT), ((b, a), TIE_WEIGHT)]
