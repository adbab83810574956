"""The preference Gaussian process of eqs. (12)–(13): BoTorch's ``PairwiseGP``, probit likelihood.

A zero-mean GP prior P(u) (12) over the latent utility u at the observed points, with an RBF kernel,
and the probit likelihood of each comparison θ_r ≻ θ_c, Φ((u(θ_r) − u(θ_c))/√2), combined into the
posterior P(u | 𝒟) (13) by BoTorch's Laplace approximation. The kernel hyperparameters (lengthscale
per dimension, output scale) are fitted by maximising the Laplace marginal likelihood with
``fit_gpytorch_mll``.

Inputs are unit-cube coordinates (the caller normalises with the fixed parameter box), in float64.
Warm start: the previous fit's hyperparameters are the initial values of the next fit, so the
optimiser starts near its optimum instead of at the prior's mode; a fit that fails keeps the
previous model, which is reported rather than raised.
"""

from __future__ import annotations

import logging
import time
from contextlib import AbstractContextManager

import gpytorch
import torch
from botorch.exceptions import ModelFittingError
from botorch.exceptions.warnings import OptimizationWarning
from botorch.fit import fit_gpytorch_mll
from botorch.models.likelihoods.pairwise import PairwiseProbitLikelihood
from botorch.models.pairwise_gp import PairwiseGP, PairwiseLaplaceMarginalLogLikelihood
from gpytorch.constraints import GreaterThan, Interval
from gpytorch.kernels import RBFKernel, ScaleKernel
from gpytorch.priors import GammaPrior, SmoothedBoxPrior
from linear_operator.utils.errors import NotPSDError
from linear_operator.utils.warnings import NumericalWarning

from app.learning.comparison_noise import BatchPositionProbit
from app.learning.config import Hyperparameters, ModelConfig
from app.learning.data import PreferenceData
from app.learning.expected_warnings import expected_warnings
from app.learning.models import FitReport
from app.learning.population import PopulationMean, PopulationPairwiseGP
from app.learning.rng import derive_seed, seeded

logger = logging.getLogger(__name__)

def make_covar_module(dim: int, config: ModelConfig) -> ScaleKernel:
    """RBF kernel, one lengthscale per dimension, scaled: k(x, x') = s·exp(−½‖(x − x')/ℓ‖²)."""
    ls_prior = GammaPrior(*config.lengthscale_prior)
    low, high = config.outputscale_range
    return ScaleKernel(
        RBFKernel(
            ard_num_dims=dim,
            lengthscale_prior=ls_prior,
            lengthscale_constraint=GreaterThan(1e-4, transform=None,
                                               initial_value=float(ls_prior.mode)),
        ),
        outputscale_prior=SmoothedBoxPrior(low, high),
        outputscale_constraint=Interval(low / 2, high * 2, initial_value=1.0),
    ).to(torch.float64)


def hyperparameters_of(model: PairwiseGP) -> Hyperparameters:
    """The kernel's raw parameters as plain lists (warm start of the next fit, snapshots)."""
    return {name: param.detach().reshape(-1).tolist()
            for name, param in model.covar_module.named_parameters()}


def _covar_module_at(dim: int, config: ModelConfig,
                     hyperparameters: Hyperparameters | None) -> ScaleKernel:
    covar = make_covar_module(dim, config)
    if hyperparameters is not None:
        with torch.no_grad():
            for name, param in covar.named_parameters():
                value = torch.tensor(hyperparameters[name], dtype=param.dtype)
                param.copy_(value.reshape(param.shape))
    return covar


def fit_model(data: PreferenceData, config: ModelConfig,
              hyperparameters: Hyperparameters | None = None, *, optimize: bool = True,
              prior_mean: PopulationMean | None = None) -> PairwiseGP:
    """Build a ``PairwiseGP`` on ``data`` and (``optimize``) fit its kernel hyperparameters.

    ``hyperparameters`` (a previous fit's :func:`hyperparameters_of`) are the starting values of the
    fit; with ``optimize=False`` they are kept, and only the Laplace approximation of eq. (13) is
    computed for the new data (a few milliseconds instead of a fit). ``prior_mean`` replaces the
    zero prior mean of eq. (12) (earlier participants, :mod:`app.learning.population`).
    Raises ``ModelFittingError`` when every attempt of ``fit_gpytorch_mll`` fails.
    """
    X, C = data.tensors()
    covar = _covar_module_at(data.dim, config, hyperparameters)
    likelihood = _likelihood(data, config)
    with kernel_evaluation(config), expected_warnings(NumericalWarning, context="PairwiseGP"):
        if prior_mean is None:
            model = PairwiseGP(X, C, likelihood=likelihood, covar_module=covar)
        else:
            model = PopulationPairwiseGP(X, C, prior_mean, likelihood=likelihood,
                                         covar_module=covar)
    if optimize:
        mll = PairwiseLaplaceMarginalLogLikelihood(model.likelihood, model)
        # fit_gpytorch_mll re-emits an OptimizationWarning for every attempt it retries.
        with kernel_evaluation(config), expected_warnings(OptimizationWarning, NumericalWarning,
                                                          context="fit"):
            options = {} if config.fit_tolerance is None else {"ftol": config.fit_tolerance}
            fit_gpytorch_mll(mll, max_attempts=config.fit_max_attempts,
                             optimizer_kwargs={"options": options})
    return model.eval()


def _likelihood(data: PreferenceData, config: ModelConfig) -> PairwiseProbitLikelihood:
    """BoTorch's probit; with noise by batch position (eq. (16)) or weighted ties, the probit with
    one relative noise and one weight per comparison (:mod:`app.learning.comparison_noise`)."""
    if not config.batch_position_noise and data.n_ties == 0:
        return PairwiseProbitLikelihood()
    noise = data.comparison_noise if config.batch_position_noise else [1.0] * len(data.comparisons)
    return BatchPositionProbit(torch.tensor(noise, dtype=torch.float64),
                               torch.tensor(data.comparison_weight, dtype=torch.float64))


def kernel_evaluation(config: ModelConfig) -> AbstractContextManager[None]:
    """How GPyTorch evaluates the kernel inside the block: through its lazy kernel tensors, or
    (``config.lazy_kernels`` off) as plain matrices. The numbers are the same; with a few dozen
    points the lazy tensors' bookkeeping costs more than the algebra (13 % of a simulated trial)."""
    return gpytorch.settings.lazily_evaluate_kernels(config.lazy_kernels)


def posterior_at(model: PairwiseGP, X: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Posterior mean E[u(x) | 𝒟] and standard deviation of the utility at the rows of ``X``."""
    # NumericalWarning: jitter added when rows of X (nearly) coincide with observed points.
    with torch.no_grad(), expected_warnings(NumericalWarning, context="posterior"):
        posterior = model.posterior(X)
    return (posterior.mean.reshape(-1),
            posterior.variance.clamp_min(0.0).sqrt().reshape(-1))


def posterior_mean(model: PairwiseGP, X: torch.Tensor) -> torch.Tensor:
    """Posterior mean utility E[u(x) | 𝒟] at the rows of ``X`` (unit cube)."""
    return posterior_at(model, X)[0]


class PreferenceModel:
    """The current model and its hyperparameters; a failed fit keeps the previous model.

    :meth:`update` either fits the hyperparameters (warm-started from the previous fit when the
    config says so) or keeps them and only recomputes the posterior for the new data (Laplace
    approximation, milliseconds). :meth:`needs_fit` says when the data have grown enough since the
    last hyperparameter fit (``ModelConfig.refit_growth``) for a fit to be due.
    """

    def __init__(self, config: ModelConfig, hyperparameters: Hyperparameters | None = None,
                 prior_mean: PopulationMean | None = None) -> None:
        self.config = config
        self.prior_mean = prior_mean
        self.model: PairwiseGP | None = None
        self.hyperparameters = hyperparameters
        self._fitted_comparisons = 0  # comparisons at the last successful hyperparameter fit

    def needs_fit(self, data: PreferenceData) -> bool:
        """True when a hyperparameter fit is due for ``data``."""
        m = len(data.comparisons)
        if m == 0:
            return False
        if self.hyperparameters is None or self._fitted_comparisons == 0:
            return True
        return m > self._fitted_comparisons * (1.0 + self.config.refit_growth)

    def update(self, data: PreferenceData, *, fit_hyperparameters: bool = True) -> FitReport:
        """Update on ``data`` (no model before the first comparison); a failed fit never raises."""
        n_points, n_comparisons = len(data.points), len(data.comparisons)
        if n_comparisons == 0:
            return FitReport(n_points=n_points, n_comparisons=0)
        previous = self.hyperparameters
        optimize = fit_hyperparameters or previous is None
        start = time.monotonic()
        initial = previous if self.config.warm_start or not optimize else None
        try:
            hyperparameters = (previous if not optimize and previous is not None else
                               hyperparameters_of(fit_model(data, self.config, initial,
                                                            prior_mean=self.prior_mean)))
            model = self._build(data, hyperparameters)
        except (ModelFittingError, NotPSDError) as exc:
            message = f"{type(exc).__name__}: {exc}; keeping the previous model"
            logger.warning("preference model update failed with %d points, %d comparisons: %s",
                           n_points, n_comparisons, message)
            return FitReport(refitted=True, hyperparameters_fitted=optimize, fit_failed=True,
                             message=message, n_points=n_points, n_comparisons=n_comparisons,
                             seconds=time.monotonic() - start)
        self.model, self.hyperparameters = model, hyperparameters
        if optimize:
            self._fitted_comparisons = n_comparisons
        return FitReport(refitted=True, hyperparameters_fitted=optimize, n_points=n_points,
                         n_comparisons=n_comparisons, seconds=time.monotonic() - start)

    @property
    def fitted_comparisons(self) -> int:
        """Comparisons at the last successful hyperparameter fit (part of a snapshot)."""
        return self._fitted_comparisons

    def restore(self, data: PreferenceData, fitted_comparisons: int) -> None:
        """Adopt the stored hyperparameters for ``data`` without fitting: the state of a snapshot.

        Without stored hyperparameters (no fit ever succeeded) a fit is attempted instead.
        """
        if self.hyperparameters is None:
            self.update(data, fit_hyperparameters=True)
            return
        if data.comparisons:
            self.model = self._build(data, self.hyperparameters)
        self._fitted_comparisons = fitted_comparisons

    def _build(self, data: PreferenceData, hyperparameters: Hyperparameters) -> PairwiseGP:
        """The model in use: built from (data, hyperparameters) without optimising, under a seed
        that depends on the data's size only (PairwiseGP perturbs its Newton start with numpy's
        global generator). So it is a function of the data and the hyperparameters alone, and a
        learner restored from a snapshot suggests exactly what the stored one would have."""
        with seeded(derive_seed(len(data.points), len(data.comparisons))):
            return fit_model(data, self.config, hyperparameters, optimize=False,
                             prior_mean=self.prior_mean)

    def best(self, data: PreferenceData) -> tuple[int, float] | None:
        """θ*: index and posterior mean of the shown point with the largest posterior mean.

        None without a model. The previous model (after a failed fit) may not know the newest
        points, so the posterior is evaluated at all of ``data``'s points, which any model can.
        """
        if self.model is None or not data.points:
            return None
        X, _ = data.tensors()
        with kernel_evaluation(self.config):
            mean = posterior_mean(self.model, X)
        index = int((mean + data.unshown_penalty()).argmax())
        return index, float(mean[index])
