"""A receptionist robot that runs for months: a new visitor every few seconds says hello and is welcomed. Its one
robot node gains children with every visit for as long as it runs — the shape of a deployment the server must
keep up with, whatever the robot's history.

Each visit, logged with the PyPI client (about 56 triples): the visitor, the shared event of what they said,
the robot's listening activity and the visitor's message, the robot's reply activity and its message. No
robot state and no emotion.
"""

from __future__ import annotations

from datetime import datetime, timedelta

from rdflib import URIRef
from semantic_log_generator import ActivityKind, SemanticSEGBLogger

ROBOT_ID = "ari"
NAMESPACE = f"https://example.org/segb/robots/{ROBOT_ID}/v1/"
INITIAL_MESSAGE = "http://kb.openrobots.org#InitialMessage"
RESPONSE_MESSAGE = "http://kb.openrobots.org#ResponseMessage"


def receptionist() -> SemanticSEGBLogger:
    """The robot's logger, with its dialogue model registered."""
    logger = SemanticSEGBLogger(
        base_namespace=NAMESPACE, robot_id=ROBOT_ID, robot_name="ARI", compact_resource_ids=True,
        namespace_prefix=ROBOT_ID,
    )  # fmt: skip
    logger.register_ml_model("dialogue", label="Dialogue LLM", version="3.2", provider="Ollama")
    return logger


def log_visit(logger: SemanticSEGBLogger, index: int, at: datetime) -> URIRef:
    """Visit `index`, starting at `at`; returns the visitor."""
    visitor = logger.register_human(f"visitor_{index}", first_name=f"Visitor {index}")
    text = f"Hello ARI, this is visit {index}."
    event = logger.get_shared_event_uri(
        event_kind="human_utterance", observed_at=at, subject=visitor, text=text, modality="speech"
    )
    listening = logger.log_activity(
        activity_id=f"listen_{index}", activity_kind=ActivityKind.LISTENING, label="Listen to the visitor",
        related_shared_events=[event], started_at=at, ended_at=at + timedelta(seconds=1),
    )  # fmt: skip
    heard = logger.log_message(
        text, message_id=f"user_{index}", language="en", message_types=[INITIAL_MESSAGE],
        generated_by_activity=listening, sender=visitor,
    )  # fmt: skip
    response = logger.log_activity(
        activity_id=f"respond_{index}", activity_kind=ActivityKind.RESPONSE, label="Reply to the visitor",
        related_shared_events=[event], started_at=at + timedelta(seconds=2), ended_at=at + timedelta(seconds=3),
        triggered_by_entity=heard,
    )  # fmt: skip
    logger.log_message(
        f"Welcome, visitor {index}!", message_id=f"robot_{index}", language="en", message_types=[RESPONSE_MESSAGE],
        generated_by_activity=response, previous_message=heard, sender=logger.robot_uri,
    )  # fmt: skip
    return visitor
