"""The sweep table: the rows of its points (:mod:`vetica_cli.rows.schema`) led by the point
key and the swept values, in grid order, with the material columns of the study's
contact model; and the units of its columns for the metadata."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..extraction import SOURCES
from ..extraction.material import contact_model
from ..rows.extract import EXTRACT_KEYS
from ..rows.schema import column_meta, material_columns, material_metadata, models_of, result_columns
from .grid import Point, Study

if TYPE_CHECKING:  # pandas is imported where a frame is built: a dry run starts without it
    import pandas as pd


def study_models(study: Study):
    """The surface models of a study's points (:func:`vetica_cli.rows.schema.models_of`)."""
    return models_of(p.config for p in study.points)


def study_methods(study: Study) -> list[str]:
    """The extraction methods of a study's points, in order of first use."""
    return list(dict.fromkeys(p.method for p in study.points))


def rows_frame(point: Point, rows: list[dict]) -> pd.DataFrame:
    """A point's rows as a frame with the columns of its surface model."""
    import pandas as pd

    return pd.DataFrame(rows, columns=result_columns([point.config.surface.surface_model], [point.method],
                                                     point.replicas))


def column_meta_of(study: Study) -> dict:
    """``column -> (unit, description)`` of every column of the study's table."""
    meta = {"point": ("", "hash of the resolved point config (names its part file)")}
    models = study_models(study)
    units = {f"surface.{k}": u for m in models for k, u in m.parameter_units.items()}
    for k in study.keys:
        if k not in EXTRACT_KEYS:
            meta[k] = (units.get(k, ""), "swept key, SI as in the config schema")
    meta.update(column_meta(models, study_methods(study), study.replicas))
    return meta


def point_contact(study: Study) -> dict:
    """Point key -> the contact model of its material columns: the study's ``material:``
    section over thesis table 6, the tip radius defaulting to the point's probe."""
    over = study.material or {}
    return {p.key: contact_model(over, p.config.probe.tip_radius, where="material") for p in study.points}


def study_material_metadata(study: Study) -> dict:
    """The contact model of the material columns (:func:`vetica_cli.rows.schema.material_metadata`)."""
    return material_metadata(study.material, [p.config.probe.tip_radius for p in study.points])


def assemble(study: Study, done: dict) -> pd.DataFrame:
    """The tidy table from the points' rows (``done``: point key -> frame): points in grid
    order, 'true' before 'reconstructed', the swept keys after the point key."""
    import pandas as pd

    columns = result_columns(study_models(study), study_methods(study), study.replicas)
    frames = []
    for p in study.points:
        df = done[p.key].reindex(columns=columns)
        lead = pd.DataFrame({"point": [p.key] * len(df)})
        for k in study.keys:
            if k not in EXTRACT_KEYS:  # extract.method is the 'method' column
                lead[k] = [p.values[k]] * len(df)
        frames.append(pd.concat([lead, df.reset_index(drop=True)], axis=1))
    table = pd.concat(frames, ignore_index=True)
    order = {s: i for i, s in enumerate(SOURCES)}
    idx = {p.key: p.index for p in study.points}
    table = (
        table.assign(_i=table["point"].map(idx), _s=table["force_source"].map(order))
        .sort_values(["_i", "_s"], kind="mergesort")
        .drop(columns=["_i", "_s"])
        .reset_index(drop=True)
    )
    table["error"] = table["error"].fillna("").astype(str)
    table["unidentified"] = table["unidentified"].fillna("").astype(str)
    table["method"] = table["method"].astype(str)
    table["stop_reason"] = table["stop_reason"].fillna("").astype(str)
    table["taps"] = table["taps"].astype("int64")
    return material_columns(table, point_contact(study), models_of(p.config for p in study.points))
