"""Report rows reshaped for reading: conversations as threads, states as snapshots, charts per report."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from segb_server.ui.charts import emotion_charts, model_usage_chart
from segb_server.ui.namesakes import Name

Row = Mapping[str, Any]

# Shown when a report has no rows, so an empty table explains itself.
EMPTY_STATES = {
    "participants": "No participants yet — no robot has logged an interaction with a human.",
    "ml-usage": "No model usage yet — robots have not logged activities that used an AI model.",
    "emotion-timeline": "No emotions yet — robots have not logged emotion readings.",
    "extreme-emotions": "No extreme emotions — no reading reaches the intensity threshold.",
    "conversations": "No conversations yet — robots have not published messages.",
    "robot-states": "No robot states yet — robots have not logged state snapshots.",
}
# The overview shows the reports in the order an audit reads them.
OVERVIEW_ORDER = ["participants", "conversations", "emotion-timeline", "extreme-emotions", "ml-usage", "robot-states"]
# What one table line stands for, where it is not one row of the report.
UNITS = {"robot-states": ("snapshot", "snapshots"), "conversations": ("message", "messages")}


@dataclass
class Thread:
    """The messages between one robot and one human, in time order."""

    robot: str
    robot_name: str
    human: str | None
    human_name: str
    messages: list[Row] = field(default_factory=list)


def conversation_threads(rows: Iterable[Row]) -> list[Thread]:
    threads: dict[tuple[str, str | None], Thread] = {}
    for row in rows:
        key = (str(row["robot"]), row.get("human"))
        if key not in threads:
            threads[key] = Thread(
                robot=key[0],
                robot_name=str(row.get("robotName") or key[0]),
                human=key[1],
                human_name=str(row.get("humanName") or key[1] or "Unattributed"),
            )
        threads[key].messages.append(row)
    return list(threads.values())


@dataclass
class Snapshot:
    """One state of one robot with all its properties."""

    robot: str
    robot_name: str
    state: str
    time: str
    location: str | None
    note: str | None
    properties: list[tuple[str, Any, str | None]] = field(default_factory=list)


def state_snapshots(rows: Iterable[Row]) -> list[Snapshot]:
    snapshots: dict[str, Snapshot] = {}
    for row in rows:
        state = str(row["state"])
        if state not in snapshots:
            snapshots[state] = Snapshot(
                robot=str(row["robot"]),
                robot_name=str(row.get("robotName") or row["robot"]),
                state=state,
                time=str(row.get("time") or ""),
                location=row.get("location"),
                note=row.get("note"),
            )
        if row.get("property") is not None:
            snapshots[state].properties.append((str(row["property"]), row.get("value"), row.get("unit")))
    return list(snapshots.values())


def view_of(name: str, table: Mapping[str, Any], names: Mapping[str, Name]) -> dict[str, Any]:
    """What the section template of report `name` needs besides the raw table: `entries` are what its table
    lists (rows, or one snapshot per state), `unit` what one of them is called."""
    rows = table.get("rows", [])
    view: dict[str, Any] = {
        "empty_message": EMPTY_STATES.get(name, "No rows."),
        "names": names,
        "entries": rows,
        "unit": UNITS.get(name, ("row", "rows")),
    }
    if name == "conversations":
        view["threads"] = conversation_threads(rows)
    elif name in ("emotion-timeline", "extreme-emotions"):
        # The extreme emotions leave the weaker readings out: a line there could pass over one unseen.
        view["charts"] = emotion_charts(rows, names, lines=name == "emotion-timeline")
    elif name == "ml-usage":
        view["bar_chart"] = model_usage_chart(rows, names)
    elif name == "robot-states":
        view["entries"] = state_snapshots(rows)
    return view
