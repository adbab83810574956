"""Preference learning for handover studies (Sect. III-C and IV of the paper).

The package knows nothing of robots or screens: parameter vectors, scale placements and pairwise
comparisons go in; the next parameter vector θ to try and the best one so far, θ*, come out.

One concept per module, composed by :class:`~app.learning.learner.PreferenceLearner`:

- :mod:`~app.learning.models`: the pydantic records at the package's boundary.
- :mod:`~app.learning.scale`: placements on the refreshing relative scale → comparisons (Fig. 1).
- :mod:`~app.learning.data`: unique points and index comparisons, the data set 𝒟 of eq. (11).
- :mod:`~app.learning.preference_model`: the PairwiseGP of eqs. (12)–(13), fitted with warm starts.
- :mod:`~app.learning.acquisition`: qNEI (eq. (14) under noise), qLogNEI, EUBO and Sobol.
- :mod:`~app.learning.planner`: the batch schedule (initial points, then θ* + q − 1 queries).
- :mod:`~app.learning.worker`: the learner in its own process, request/response with a fallback.
- :mod:`~app.learning.simulation`, :mod:`~app.learning.simulated_study`: the simulated study of Sect. IV.
"""
