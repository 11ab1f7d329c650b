"""The whole-cycle fit as referee of another method on the same record: run once per record
(kept on ``record.memo``, also filled by :func:`vetica_cli.extraction.extract_many` when the fit
was asked for), its estimates judge the tap methods' (:func:`.methods.tapchecks.referee`) and its
fitted surface's force through the whole band measures what the record's low-pass does to their
answers (:func:`.uncertainty.band_term`)."""

from __future__ import annotations


def referee_fit(method, record) -> tuple[dict, object]:
    """``(estimates, forward)`` of ``method.referee``'s fit on ``record`` (:func:`fit_on`)."""
    return fit_on(record, method.referee)


def fit_on(record, key: str | None) -> tuple[dict, object]:
    """``(estimates, forward)`` of the method ``key``'s fit on ``record`` with its default
    options and its own checks (a flagged quantity is ``identifiable=False``): ``({}, None)`` when
    ``key`` is None, that method cannot fit this record's surface model, or it refused the
    record; ``forward`` (:class:`.fullfit.method.ForwardForce`) None when the fit kept none."""
    from .base import METHODS
    from .sanity import check

    full = METHODS.get(key) if key else None
    model = getattr(record, "model", None)
    if full is None or model is None or model.key not in full.surface_models or not hasattr(record, "memo"):
        return {}, None
    key = ("referee", full.key, id(record.f), record.z1)
    if key not in record.memo:
        try:
            fit = full.run(record, full.options({}))
            check(fit, record, None, full)  # its own checks (no referee for the fit): a flagged quantity referees nothing
            record.memo[key] = fit.estimates
        except Exception:  # noqa: BLE001 - the fit refuses the record: no referee
            record.memo[key] = {}
    return record.memo[key], record.memo.get(("forward", full.key, id(record.f), record.z1))
