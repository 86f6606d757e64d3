"""What each finding on `/findings` is about, by name (`about_names`): a node the log gave no name by its robot,
kind and time, a label several robots' nodes share with its robot, never an id."""

from __future__ import annotations

from typing import Any

from segb_server.ui.routes.findings import about_names

ARI, MIRROR = "https://example.org/robots/ari/v1/", "https://example.org/robots/mirror/v1/"
ROBOTS = {ARI + "robot_ari": "ARI", MIRROR + "robot_mirror": "Emotion Mirror", ARI + "human_maria": "Maria (ARI)"}


def finding(
    focus: str, robot: str, about: dict[str, Any] | None, time: str = "2026-03-10T10:00:02.5Z"
) -> dict[str, Any]:
    return {"focus": focus, "robot": robot, "time": time, "about": about and {"id": focus, **about}}


def test_a_node_the_log_gave_no_name_is_told_by_its_robot_kind_and_time() -> None:
    state = ARI + "state_state_2"
    names = about_names([finding(state, ARI + "robot_ari", {"label": "state_state_2", "kind": "state"})], ROBOTS)
    assert names == {state: "ARI's state at 10:00:02.500"}


def test_a_node_the_graph_does_not_hold_yet_is_told_by_the_words_of_its_iri() -> None:
    emotion = ARI + "emotion_ed3176a40eb344788c8fada902925755"
    assert about_names([finding(emotion, ARI + "robot_ari", None)], ROBOTS) == {emotion: "emotion"}


def test_the_same_words_of_two_robots_are_told_apart_by_robot() -> None:
    said = {"label": "Tell me more.", "kind": "message"}
    found = [
        finding(ARI + "message_robot_2", ARI + "robot_ari", said),
        finding(ARI + "message_robot_4", ARI + "robot_ari", said),
        finding(MIRROR + "message_robot_2", MIRROR + "robot_mirror", said),
        finding(ARI + "message_user_1", ARI + "robot_ari", {"label": "Hi!", "kind": "message"}),
    ]
    assert about_names(found, ROBOTS) == {
        ARI + "message_robot_2": "Tell me more. (ARI)",
        ARI + "message_robot_4": "Tell me more. (ARI)",
        MIRROR + "message_robot_2": "Tell me more. (Emotion Mirror)",
        ARI + "message_user_1": "Hi!",
    }


def test_a_robot_or_a_person_is_named_as_the_filters_name_them() -> None:
    maria = ARI + "human_maria"
    assert about_names([finding(maria, ARI + "robot_ari", {"label": "Maria", "kind": "human"})], ROBOTS) == {
        maria: "Maria (ARI)"
    }


def test_a_label_whose_robot_is_unknown_stays_as_it_is() -> None:
    model = "https://example.org/models/llm"
    found = [
        finding(model, "https://example.org/robots/r2d2", {"label": "llama3.2", "kind": "model"}),
        finding(ARI + "model_llm", ARI + "robot_ari", {"label": "llama3.2", "kind": "model"}),
    ]
    assert about_names(found, ROBOTS) == {model: "llama3.2", ARI + "model_llm": "llama3.2"}
