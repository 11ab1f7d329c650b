"""Whole-cycle model inversion: ``vetica extract RUN --method full``.

VETICA (thesis 3.3) reads a few samples of each tap.  This method uses every
sample of the recorded steady periods: the measured tip trajectory
``z_tip(t)`` drives the massless Zener SLS surface (thesis
3.2, appendix C: contact when the gap is <= a0, creep out of contact,
separation when the surface would have to hold the tip with more than the
adhesion) -- or the Wiechert surface, ``k_inf`` and N Maxwell arms --
and bounded least squares finds ``k_inf, k0, cd`` (``k_inf, k_1, cd_1, ...,
k_N, cd_N``; optionally ``H R``) for which the predicted force matches the
measured one::

    minimise  sum_i ( Fts_model(t_i; k_inf, k0, cd[, H R]) - F_i )^2 / F_peak^2
    over      ln k_inf, ln k0, ln cd [, ln H R]      (scipy least_squares, 'trf')

Choices (see the module functions for details):

* **Forward model** (:mod:`vetica_cli.core.prescribed`, :mod:`.model`): the simulator's own surface
  updates (:mod:`vetica_cli.core.sls`; for N arms the N-arm kernel of
  :mod:`~vetica_cli.core.prescribed`, whose coefficient derivatives come from
  a complex step; one arm keeps the scalar SLS kernel, 3-4x faster per
  sample), once per sample of the record, with their
  exact tangent-linear derivatives (the Jacobian of the fit comes out of the
  same pass).  Where the simulator's lagged gap -> attraction -> surface
  feedback matters (out of contact within ~1 nm, and across a separation)
  the sample interval is split into the simulator's own steps
  (``substeps = print_step/dt`` from the metadata, else print_step/0.025 ns), the tip
  interpolated linearly: without this the snap-off transients differ by up
  to 2.6 % of the peak force over a few samples and bias cd by ~6 % at
  cd = 1e-2 kg/s.  Elsewhere in contact the dashpot is updated once per
  sample with the simulator's own linear-target step (the surface moving
  linearly across the sample: :mod:`vetica_cli.core.coefficients`), so the
  model reproduces the simulator's force at its true parameters to 4e-7 of
  the peak on the worked example (RMS; 9.7e-5 with the step that held the
  surface at the sample, whose relaxation read ``(h - dt)/2`` late).
* **Surface height** ``s0`` (the undeformed surface in the record's tip
  coordinate, which for an instrument has an unknown offset).  Start value
  from ``Z1``, the tip position at the first force minimum of the approach
  (thesis eq. 84): there the gap is ``a0`` and the surface is pulled up to
  ``X1 = (k0 Xd1 + Fa(a0))/Kg`` (``vdw_on_surface``; ``k0 Xd1/Kg`` without
  the pull), so ``s0 = Z1 - a0 - X1``, with ``Xd1`` (the dashpot's creep
  under the attraction during the approach, ~15 pm on the worked example)
  from the same model run over the approach record (surface undeformed at
  its start).  ``Z1`` is only known to within the tip's travel in one
  sample (the minimum is the last sample out of contact or the first in
  it): 2.8 pm at cd = 1e-2, which alone gives a 0.1 % RMS force misfit.
  So, when the record has its approach segment, ``s0`` is fitted too, with
  the approach samples (the first tap, on an undeformed surface) added to
  the residuals.  Without one but with ``Z1`` (given, or from the metadata) the
  first periods are fitted with ``s0`` pinned to the ``Z1`` value (the dashpots
  taken undeformed at the first contact), then the whole window frees it.
  Without ``Z1`` at all (a record as an instrument writes it) ``s0`` is fitted
  from the steady taps alone, starting from the tip position at the steady
  contacts, with a larger evaluation budget: for a dashpot too slow to creep
  much between taps the height and the split of Kg between ``k_inf`` and that
  dashpot form a long valley (on the periodic orbit the arms sit at the
  surface's mean position ``<X> = -<Fts>/k_inf``), and the output warns that
  the split may be wrong (measured at 50 kHz: the worked example, cd 3e-5 kg/s
  at 32:1, and cd 3e-4 kg/s at 16:1 recovered within 0.002 %; cd 1e-3 and 1e-2
  kg/s at 16:1 not, k_inf off by several hundred %; with ``Z1`` given, all
  within 0.3 %).
* **Records as measured.**  What the record does not say is fitted or assumed,
  and the output says which: ``H R`` is fitted (from the adhesion, the force
  minimum ``-H R/(6 a0^2)``, as its start) unless ``--hamaker`` or the metadata
  gives ``H`` (then with ``--tip-radius`` or the metadata's R, else the
  thesis's 10 nm); ``a0`` comes from ``--a0`` or the metadata, else the thesis's
  0.2 nm is assumed (measured: a0 off by 50 % moves k0, k_inf, cd by < 0.02 %
  and H R by -47 %, and raises the RMS residual 2000-fold); whether the
  attraction pulls the surface too (``vdw_on_surface``) comes from the option
  or the metadata, else both are fitted and the smaller residual kept.
  Without the simulator's ``dt`` the surface is sub-stepped near the surface at
  the thesis's 0.025 ns.
* **Several arms.**  Fitted arm by arm on the first periods: the SLS fit,
  then each further arm from candidates whose relaxation time is 1e-3 ... 1e3
  times a present arm's, its spring taken from the arms or from ``k_inf``,
  each tried for a few evaluations, the best fitted.  Arms are
  exchangeable; the result orders them by relaxation time, rank for rank
  onto the record's own arms when its metadata has them (else fastest first).
* **State at the window start.**  The steady window spans whole drive
  periods with the base fixed, so the surface state at its start equals the
  state at its end.  The dashpot position ``Xd0`` there is solved for with
  Newton's method on ``Xd_end(Xd0) = Xd0`` (``dXd_end/dXd0``, N x N for N arms, from the
  tangent-linear kernel; the map is affine for a fixed contact schedule, so
  one or two passes do even when nothing relaxes within the window, where
  iterating the window would need ~tau/window repetitions); the periodicity
  residual is reported.  A record taken before the surface settled (tau_c
  comparable to the run's 3-30 ms) is not periodic, and neither is a
  thermal record (the tip's thermal motion moves the dashpots): ``state='auto'``
  (the default) then frees ``Xd0`` as one more fit parameter when a linearised
  step says that removes more than half the residual, or more than noise
  could (an F test at p = 1e-3: on noisy stripped 300 K records the state
  removed 1-36 % of the residual, and held periodic k_inf was 0.09 % off at a
  0.03 % sigma); ``'periodic'`` and ``'free'`` force either.
* **Decimation.**  The forward model runs over every sample; far from the
  surface (gap > 5 nm, attraction < 0.2 % of Fa(a0)) it advances in exact
  steps of ``block`` samples.  Residuals are taken at every
  ``near_stride``-th sample (4) where the measured tip is within 5 nm of Z1
  (contact and the van der Waals range) and every ``far_stride``-th (256)
  elsewhere: ~66 000 residuals for 1.6e6 samples.  Coarse to fine: the
  start scan and a first fit use the first drive period only (its periodic
  state is the window's), then the whole window refines it.
* **Start.**  VETICA's answer on the first 3 taps when it has a plausible
  one, else ``k0 = 0.9 Kg``, ``k_inf = 0.1 Kg`` from the loading slope; a
  start whose Kg is more than a decade off that slope is rescaled onto it.
  Then a scan of cd over 1e-10 .. 1e2 kg/s (every two decades) with one
  Gauss-Newton step on the other parameters at each cd picks the start; a start
  that fits to 5 % of the peak force after its own step has its dashpot's regime
  right, and only the grid's cd within two decades of it are tried (the same pick
  on every record measured, with about half the model passes on a scan pixel).
  A first-period fit still poor (RMS residual above 3x the noise floor and 1 % of
  the peak) is fitted again: after a near-only scan over the whole grid; from the
  best cd below the frozen plateau where that end won; then from the scan's other
  points in the order of their cost until one is not poor; then from the generic
  split; then from ``k_inf`` = the loading slope under an arm 4, 16 or 64 times
  stiffer (an arm faster than a tap's loading has relaxed during it: the slope is
  k_inf, not Kg); then, from 0.4 % of the peak, from the best of the arm's spring and the
  surface height profiled at its dashpot (an arm that relaxes within a few samples shows its
  spring only in the impact: a valley narrow in both) (the best kept each time:
  ``method.POOR_FIT``, ``POOR_STARTS``, ``GENERIC_RETRY``, ``FAST_ARM_RETRY``,
  ``ARM_PROFILE_RETRY``).  A first-period fit that ends on the frozen plateau (cd beyond
  the grid's end) is fitted again from the scan's best point below it
  (``FROZEN_RETRY``).
* **Uncertainty.**  ``cov = s^2 (J^T J)^-1`` with ``s^2`` the residual
  variance, J in log-parameters (square roots of the diagonal = relative
  1-sigma), with ``Xd0`` counted as unknown (conservative: it does not lean
  on the periodic state; the periodic-state values are in ``info``).  For
  noise-free simulations ``s`` is systematic model mismatch, and the actual
  errors exceed the 1-sigma values by ~10x (cd = 1e-2 kg/s; 1 pm position
  noise) up to ~5000x (worked example, with the held contact step that
  the kernels no longer take: 1-sigma 4e-8, error 2e-4).  Added in quadrature where the residual is more
  the model's error than noise, **the misfit term**: the residual's part
  that repeats every drive period over each dashpot's force signature, the
  change of ``ln cd`` a misfit along that signature would make (noise-free
  16:1 at cd 100 kg/s, 0.5 ns: cd +11.8 % at a Jacobian 1-sigma of 0.44 %,
  the term 9.4 %); on a force low-passed below the Nyquist frequency it is
  left to the band term (the repeating residual is then the band's smear).
  The larger of that error and a tap-robust sandwich counts; on such a force the
  band's own noise through the fit (white within the band: neighbouring rows share
  it) replaces ``s^2 (J^T J)^-1``, and the surface height's reading error (one steady
  tap's, the approach tap's: it pins the height alone) is added in quadrature.
  A parameter is flagged not identifiable when
  its 1-sigma exceeds 100 %, when it sits at a bound, when the fit stopped
  far from converged, or when the fitted dashpot does not act within the
  record (its force signature within a tap is below 10x the RMS residual:
  cd has only a lower bound and only Kg = k0 + k_inf is determined; or it
  relaxes within one sample: cd has only an upper bound).

Modules: :mod:`.model` (the forward model and its periodic state), :mod:`.fit`
(least squares and the cd scan), :mod:`.start` (starting point),
:mod:`.uncertainty` (covariance, identifiability), :mod:`.method` (the
registered method ``full``: coarse-to-fine stages and the result).
"""

from .method import FullFit  # registers 'full'

__all__ = ["FullFit"]
