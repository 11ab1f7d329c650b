"""The whole-cycle fit as referee of another method on the same record: run once per record
(kept on ``record.memo``, also filled by :func:`vetica_cli.extraction.extract_many` when the fit
was asked for), its estimates judge the tap methods' (:func:`.methods.tapchecks.referee`) and its
fitted surface's force through the whole band measures what the record's low-pass does to their
answers (:func:`.uncertainty.band_term`)."""

from __future__ import annotations


def memo_key(kind: str, key: str, record) -> tuple:
    """The ``record.memo`` key of what the method ``key``'s fit on ``record`` left there: ``kind``
    ``"referee"`` (its estimates on its default options, checked) or ``"forward"`` (its fitted
    surface's forward model); tied to the record's force array and Z1, so a copy of the record with
    another force (a narrower band, a model record) finds none."""
    return (kind, key, id(record.f), record.z1)


def forward_on(record, key: str):
    """The forward model the method ``key``'s fit on its default options left on ``record``, or None."""
    return record.memo.get(memo_key("forward", key, record))


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
    key = memo_key("referee", full.key, record)
    if key not in record.memo:
        try:
            fit = full.run(record, full.options({}))
            check(fit, record, None, full)  # its own checks (no referee for the fit): a flagged quantity referees nothing
            record.memo[key] = fit.estimates
        except Exception:  # noqa: BLE001 - the fit refuses the record: no referee
            record.memo[key] = {}
    return record.memo[key], forward_on(record, full.key)
