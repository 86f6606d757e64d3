"""An incident to investigate, logged with the real PyPI client: the hospital lobby (scenarios.lobby) and what
follows it — TIAGo hears someone it cannot name, decides what to do, and later learns that it was Juan (a late
link: the message gets its sender in a later post); ARI watches Maria leave and logs what it saw. Every step
publishes the changed robot's whole graph, and the incident ends with both robots publishing everything again.
"""

from __future__ import annotations

from semantic_log_generator import ActivityKind, SEGBPublisher

from tests.support.scenarios import INITIAL, Scenario, at, lobby
from tests.support.settle import settle


def incident() -> Scenario:
    scenario = lobby()
    ari, tiago = scenario.loggers["ari"], scenario.loggers["tiago"]
    iris = scenario.iris

    def someone_asks() -> None:
        listen = tiago.log_activity(
            activity_id="listen_someone", activity_kind=ActivityKind.LISTENING, label="Listen", started_at=at(25)
        )
        iris["someone_1"] = tiago.log_message(
            "Is anyone there?", message_id="someone_1", language="en", message_types=[INITIAL],
            generated_by_activity=listen,
        )  # fmt: skip
        iris["listen_someone"] = listen

    def tiago_decides() -> None:
        iris["guide_juan"] = tiago.log_activity(
            activity_id="guide_juan",
            activity_kind=ActivityKind.DECISION,
            label="Guide Juan to the pharmacy",
            started_at=at(26),
            triggered_by_entity=iris["someone_1"],
        )

    def it_was_juan() -> None:
        # The same message, logged again with its sender: the sender reaches the server in a later post.
        tiago.log_message(
            "Is anyone there?", message_id="someone_1", language="en", message_types=[INITIAL],
            generated_by_activity=iris["listen_someone"], sender=iris["juan"],
        )  # fmt: skip

    def maria_leaves() -> None:
        event = ari.get_shared_event_uri(event_kind="human_exit", observed_at=at(30), subject=iris["maria"])
        watch = ari.log_activity(
            activity_id="watch_door",
            activity_kind=ActivityKind.HUMAN_DETECTION,
            label="Watch the door",
            related_shared_events=[event],
            started_at=at(30),
        )
        iris["maria_left"] = ari.log_observation(
            observation_id="maria_left", label="Maria left the lobby", generated_by_activity=watch
        )
        iris["watch_door"] = watch

    scenario.steps += [
        ("tiago", someone_asks),
        ("tiago", tiago_decides),
        ("ari", maria_leaves),
        ("tiago", it_was_juan),
    ]
    return scenario


def publish_incident(base_url: str) -> Scenario:
    """Publish the incident step by step, then every robot's whole graph once more (a re-publish changes
    nothing); return once the server shows it all."""
    scenario = incident()
    scenario.publish_all(base_url)
    for name, robot in scenario.loggers.items():
        robot.publish(SEGBPublisher(base_url=base_url, default_user=name))
    settle(base_url)
    return scenario
