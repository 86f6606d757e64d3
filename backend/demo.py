"""The demo dataset: two robots' logs made by the real robot client, so a first look at the reports and the
graph explorer shows every kind of record the server audits.

* ARI runs the emotion-mirror mission (`examples/emotion_mirror`) with Maria: the example's default script
  of expressions, utterances and replies. Its face model carries training lineage (dataset, evaluation).
* Both robots ask the server's shared-context resolver which shared event an utterance is, as the example
  robot does: through the API's resolver service when the demo is loaded in-process, over
  `POST /shared-context/resolve` when it is published. TIAGo stands in the same lobby and hears Maria's first
  utterance too (same subject, text and time: *matched*, one shared event for both robots' activities). It
  also overhears her second one half a second late without seeing who spoke: a near miss the resolver keeps
  apart as *ambiguous*, so the shared-context page has one case to review.
* Every expression a robot reads on a face is about the shared event of the utterance it came with, as the
  example robot (and the tutorial's) logs it: the reference web UI's human-emotion panels show only such readings.
* Then Carlos talks to TIAGo. TIAGo's last state (docking) has no location: a case the reference reports drop and
  this server keeps.

Timestamps are fixed, and so are the shared-context URIs the resolver derives from them. Some IRIs the client
mints are random (emotions, state properties), so the Turtle differs between runs; loading it twice would
duplicate those nodes, hence the "only when empty" rules.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from datetime import UTC, datetime, timedelta
from typing import TYPE_CHECKING, Any

import httpx
from pyoxigraph import RdfFormat
from rdflib import Graph

from segb_server.backend.api.routes.shared_context import ResolveRequest
from segb_server.backend.services.container import Services
from segb_server.backend.services.errors import ServiceError
from segb_server.backend.services.ingest.payloads import RdfPayload
from segb_server.backend.services.ingest.service import IngestResult

if TYPE_CHECKING:  # the robot code is imported when a demo is built, not whenever the CLI starts
    from semantic_log_generator.types import SharedEventRequest

    from segb_server.backend.services.shared_context.service import SharedContextService
    from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission

Resolver = Callable[[str], Callable[["SharedEventRequest"], str | None]]  # robot IRI -> the client's resolver

logger = logging.getLogger("segb.demo")

DEMO_USER = "segb-demo"
ARI_ROBOT = "https://example.org/segb/robots/ari/v1/robot_ari"
CARLOS_AT = datetime(2026, 3, 10, 10, 1, 0, tzinfo=UTC)
SETTLE_SECONDS = 60.0
OVERHEARD_LATE = timedelta(seconds=0.5)  # close enough to be a candidate, too late (and unattributed) to match


class DemoError(ServiceError):
    """The demo dataset cannot be made or delivered; the message says what to do."""

    code = "demo_unavailable"


def demo_turtle(resolver: Resolver) -> str:
    """Both robots' graphs, merged, as one Turtle document (as if their two processes had published)."""
    graphs = [mission.logger.graph for mission in _run_missions(resolver)]
    merged = Graph()
    for graph in graphs:
        for prefix, namespace in graph.namespaces():
            merged.bind(prefix, namespace, override=False)
        merged += graph
    return merged.serialize(format="turtle")


def load_demo(services: Services) -> IngestResult | None:
    """Ingest the demo when the store holds nothing, through the server's own ingest service and journal (so
    the receipt tells where the data came from), resolving the robots' shared events with its own
    shared-context service; None when the store already has data. Blocking: run it in a worker thread."""
    present = services.store.count()
    if present:
        logger.info("demo dataset not loaded: the store already holds %d triples", present)
        return None
    turtle = demo_turtle(lambda robot: _in_process(services.shared_context, robot))
    payload = RdfPayload(turtle.encode("utf-8"), RdfFormat.TURTLE, claimed_user=DEMO_USER)
    result = services.ingest.ingest(payload, actor=DEMO_USER)
    # The first page a newcomer opens shows the demo: wait until the store and the reports' rows have it.
    if services.writes.wait_applied(result.sequence, SETTLE_SECONDS):
        services.writes.wait_viewed(result.sequence, SETTLE_SECONDS)
    logger.info(
        "demo dataset loaded: %d triples (robots ARI and TIAGo, humans Maria and Carlos; log_id=%s)",
        result.triples_new,
        result.log_id,
    )
    return result


def _in_process(service: SharedContextService, robot: str) -> Callable[[SharedEventRequest], str | None]:
    """What `HTTPSharedContextResolver` asks over HTTP, asked of the service directly (same validation)."""

    def resolve(request: SharedEventRequest) -> str | None:
        asked = ResolveRequest(
            event_kind=request.event_kind,
            observed_at=request.observed_at,
            subject_uri=str(request.subject) if request.subject is not None else None,
            modality=request.modality,
            text=request.text,
            robot_uri=robot,
        )
        return service.resolve(asked.observation(DEMO_USER)).shared_context_uri

    return resolve


def publish_demo(server: str, token: str | None = None) -> str:
    """POST the demo to a running server with the robot client's `SEGBPublisher`; returns what happened.
    A server that already shows ARI's interactions is left alone, so running this twice adds nothing."""
    server = server.rstrip("/")
    headers = {"Authorization": f"Bearer {token}"} if token else {}
    try:
        known = httpx.get(
            f"{server}/reports/participants", params={"robot": ARI_ROBOT, "limit": 1}, headers=headers, timeout=10
        )
    except (httpx.HTTPError, httpx.InvalidURL) as error:
        raise DemoError(f"cannot reach the SEGB server at {server} ({error}); start one with `segb serve`") from None
    # Without the auditor role the check is refused (401/403): publish anyway, the logger role suffices.
    if known.status_code == 200 and known.json()["rows"]:
        return f"{server} already has the demo dataset (ARI's interactions are there): nothing sent"
    from requests import RequestException
    from semantic_log_generator import SEGBPublisher
    from semantic_log_generator.shared_context import HTTPSharedContextResolver

    publisher = SEGBPublisher(base_url=server, token=token, default_user=DEMO_USER)
    # A resolver that fails must stop the demo: its silent local fallback would mint other shared events.
    resolver = HTTPSharedContextResolver(base_url=server, token=token, raise_on_error=True)
    try:
        response: dict[str, Any] = publisher.publish_turtle(demo_turtle(lambda robot: resolver))
    except (RequestException, RuntimeError, ValueError) as error:  # ValueError: a resolve answer without a URI
        raise DemoError(f"publishing the demo to {server} failed: {error}") from None
    finally:
        resolver.close()
    return (
        f"demo dataset published to {server}: {response.get('triples_received')} triples, "
        f"{response.get('triples_new')} new (robots ARI and TIAGo, humans Maria and Carlos)"
    )


def _run_missions(resolver: Resolver) -> list[EmotionMirrorMission]:
    from semantic_log_generator import RobotStateSnapshot

    from segb_server.examples.emotion_mirror.driver import play
    from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission, RobotConfig
    from segb_server.examples.emotion_mirror.script import Utterance, default_script

    script = default_script()
    ari_config = RobotConfig(
        robot_id="ari", robot_name="ARI", base_namespace="https://example.org/segb/robots/ari/v1/", location="lobby"
    )
    ari = EmotionMirrorMission.start(
        ari_config,
        human_id=script.human_id,
        human_name=script.human_name,
        shared_event_resolver=resolver(ari_config.base_namespace + "robot_ari"),
    )
    _training_lineage(ari)
    for _ in play(ari, script):
        pass

    tiago_config = RobotConfig(
        robot_id="tiago",
        robot_name="TIAGo",
        base_namespace="https://example.org/segb/robots/tiago/v1/",
        location="lobby",
    )
    tiago = EmotionMirrorMission.start(
        tiago_config,
        human_id=script.human_id,
        human_name=script.human_name,
        human=ari.human,
        shared_event_resolver=resolver(tiago_config.base_namespace + "robot_tiago"),
        battery=0.47,
    )
    # TIAGo overhears Maria's first utterance (ARI answers it): same subject IRI, text and time as on ARI's
    # side, so the resolver matches it to ARI's shared event.
    first, second = [event for event in script.events if isinstance(event, Utterance)][:2]
    tiago.on_user_utterance(first.text, first.at)
    _overhear_unattributed(tiago, second.text, second.at + OVERHEARD_LATE)

    # The mission attends one person at a time; TIAGo now turns to Carlos.
    tiago.human = tiago.logger.register_human("carlos", first_name="Carlos")
    tiago.on_face_expression("angry", CARLOS_AT, confidence=0.79, intensity=0.88)
    question = tiago.on_user_utterance("Where is the pharmacy? I have been waiting for ages.", CARLOS_AT + _s(1))
    tiago.respond(question, CARLOS_AT + _s(2.5))
    tiago.logger.log_robot_state(
        RobotStateSnapshot(
            timestamp=CARLOS_AT + _s(60),
            battery_level=0.46,
            mission_phase="docking",
            autonomy_mode="autonomous",
            note="Going back to the charger",
        ),
        state_id="state_docking",
    )
    return [ari, tiago]


def _overhear_unattributed(mission: EmotionMirrorMission, text: str, at: datetime) -> None:
    """Speech heard without seeing the speaker: no subject, no sender. The resolver cannot tell whether it is
    the utterance another robot logged a moment before, and leaves it to a reviewer."""
    from semantic_log_generator import ActivityKind

    from segb_server.examples.emotion_mirror.mission import INITIAL_MESSAGE

    log = mission.logger
    event = log.get_shared_event_uri(event_kind="human_utterance", observed_at=at, text=text, modality="speech")
    listening = log.log_activity(
        activity_id="overhear_1",
        activity_kind=ActivityKind.LISTENING,
        label="Overhear speech (speaker not seen)",
        related_shared_events=[event],
        started_at=at,
        ended_at=at + _s(0.8),
    )
    log.log_message(
        text, message_id="overheard_1", language="en", message_types=[INITIAL_MESSAGE], generated_by_activity=listening
    )


def _training_lineage(ari: EmotionMirrorMission) -> None:
    """How ARI's face model was made: a training run with a dataset in and an evaluation out."""
    from semantic_log_generator import ActivityKind

    log = ari.logger
    started = datetime(2026, 2, 2, 8, 0, tzinfo=UTC)
    run = log.log_activity(
        activity_id="train_face_emotion",
        activity_kind=ActivityKind.ML_RUN,
        label="Train the emotion CNN",
        started_at=started,
        ended_at=started + timedelta(hours=6),
    )
    log.link_ml_run_input(run, log.register_dataset("fer2013", label="FER-2013 facial expressions"))
    log.link_ml_run_output(run, ari.models["face"])
    log.link_ml_run_output(run, log.register_model_evaluation("face_emotion_accuracy", value=0.71, label="Accuracy"))


def _s(seconds: float) -> timedelta:
    return timedelta(seconds=seconds)
