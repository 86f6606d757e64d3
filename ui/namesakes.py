"""Telling apart things that share a label: two people called Maria logged by two robots, one model name
registered by three robots. A label used by one IRI is shown as it is; a label several IRIs share gets a
qualifier that differs between them, so tables, filters and charts never show two identical names."""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from segb_server.ui.display import short_iri

_SEGMENTS = re.compile(r"[^/#]*[/#]?")


@dataclass(frozen=True)
class Name:
    label: str
    qualifier: str = ""  # empty when the label alone is unambiguous

    def __str__(self) -> str:
        return f"{self.label} ({self.qualifier})" if self.qualifier else self.label


def tell_apart(labels: Mapping[str, str], hints: Mapping[str, str] | None = None) -> dict[str, Name]:
    """`labels` maps IRIs to labels. Where IRIs share a label (ignoring case), each is qualified by its hint
    (say, the robots that used a model) when the hints tell them apart, else by the part of its IRI from
    the first segment that differs."""
    groups: dict[str, list[str]] = {}
    for iri, label in labels.items():
        groups.setdefault(label.casefold(), []).append(iri)
    names: dict[str, Name] = {}
    for iris in groups.values():
        if len(iris) == 1:
            names[iris[0]] = Name(labels[iris[0]])
            continue
        hinted = [(hints or {}).get(iri, "") for iri in iris]
        qualifiers = hinted if all(hinted) and len(set(hinted)) == len(iris) else differing_paths(iris)
        names.update((iri, Name(labels[iri], qualifier)) for iri, qualifier in zip(iris, qualifiers, strict=True))
    return names


def differing_paths(iris: list[str]) -> list[str]:
    """Each IRI from the first path segment where they differ: `…/ari/v1/human_maria` and
    `…/mirror/v1/human_maria` give `ari/v1/human_maria` and `mirror/v1/human_maria`."""
    split = [[part for part in _SEGMENTS.findall(iri) if part] for iri in iris]
    common = 0
    while all(len(parts) > common + 1 for parts in split) and len({parts[common] for parts in split}) == 1:
        common += 1
    return ["".join(parts[common:]).rstrip("/#") or iri for iri, parts in zip(iris, split, strict=True)]


# Report columns holding an entity's IRI, the column with its display name, and whether the robots in the
# same row tell namesakes apart (a model or dataset is best known by the robot that used it; a person by every
# robot that met them, `met`, since two robots can meet the same person).
ENTITY_COLUMNS = (
    ("human", "humanName", False),
    ("robot", "robotName", False),
    ("target", "targetName", False),
    ("model", "modelName", True),
    ("dataset", "datasetName", True),
)


def entity_names(
    tables: Iterable[Iterable[Mapping[str, object]]], met: Mapping[str, str] | None = None
) -> dict[str, Name]:
    """One name per entity across every row of these report tables, namesakes qualified: a model or dataset by
    the robots that used it in these rows, a person by the robots that met them (`met`, from the participants
    report, so a person has one name on every page), else by the part of their IRIs that differs."""
    labels: dict[str, str] = {}
    robots: dict[str, set[str]] = {}
    for rows in tables:
        for row in rows:
            for column, name_column, by_robot in ENTITY_COLUMNS:
                iri = row.get(column)
                if not iri:
                    continue
                labels.setdefault(str(iri), str(row.get(name_column) or short_iri(iri)))
                if by_robot and row.get("robotName"):
                    robots.setdefault(str(iri), set()).add(str(row["robotName"]))
    hints = {**(met or {}), **{iri: ", ".join(sorted(names, key=str.casefold)) for iri, names in robots.items()}}
    return tell_apart(labels, hints)
