"""Run the emotion-mirror robot against a SEGB server (`python3 -m segb_server.examples.emotion_mirror.run`).

Replays a script (the built-in one with Maria, or `--script file.json`) into the mission, publishing the
robot's whole graph with `SEGBPublisher` after every event (or, with `--publish new`, what it added since the
last publish), and prints one line per event.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import httpx
from requests import RequestException
from semantic_log_generator import SEGBPublisher, SemanticSEGBLogger
from semantic_log_generator.shared_context import HTTPSharedContextResolver

from segb_server.examples.emotion_mirror.driver import play
from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission, RobotConfig
from segb_server.examples.emotion_mirror.publishing import NewOnly
from segb_server.examples.emotion_mirror.replier import DEFAULT_MODEL, ollama_replier
from segb_server.examples.emotion_mirror.script import Script, ScriptError, default_script, load_script

DEFAULT_SERVER = "http://127.0.0.1:5000"


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        script = load_script(args.script) if args.script else default_script()
    except ScriptError as error:
        return _fail(f"bad script: {error}", status=2)
    server = args.server.rstrip("/")
    problem = _unreachable(server)
    if problem:
        return _fail(f"cannot reach the SEGB server at {server} ({problem}); start one with `segb serve`")
    try:
        _run(server, args, script)
    except (RequestException, RuntimeError) as error:
        hint = " (pass --token; `segb token --username mirror --role logger` mints one)" if "401" in str(error) else ""
        return _fail(f"publishing to {server} failed: {error}{hint}")
    return 0


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python3 -m segb_server.examples.emotion_mirror.run",
        description="Replay a conversation into the emotion-mirror robot.",
    )
    parser.add_argument("--server", default=DEFAULT_SERVER, help=f"SEGB API base URL (default {DEFAULT_SERVER})")
    parser.add_argument("--token", help="bearer token with the logger role, when the server has SECRET_KEY set")
    parser.add_argument("--script", type=Path, help="JSON script of timed expressions and utterances")
    parser.add_argument("--ollama-host", help="Ollama server (default: OLLAMA_HOST, else http://127.0.0.1:11434)")
    parser.add_argument("--ollama-model", default=DEFAULT_MODEL, help=f"Ollama model (default {DEFAULT_MODEL})")
    parser.add_argument(
        "--publish",
        choices=("whole", "new"),
        default="whole",
        help="send the robot's whole graph after every event, as the tutorial does (default), or only the triples "
        "added since the last publish (publishing.py)",
    )
    return parser


def _run(server: str, args: argparse.Namespace, script: Script) -> None:
    config = _config(args.ollama_model)
    publisher = SEGBPublisher(base_url=server, token=args.token, default_user=config.robot_id)
    last: dict[str, Any] = {}
    new_only = NewOnly(publisher) if args.publish == "new" else None

    def publish(logger: SemanticSEGBLogger) -> None:
        last.update(new_only.publish(logger) if new_only else logger.publish(publisher))

    mission = EmotionMirrorMission.start(
        config,
        human_id=script.human_id,
        human_name=script.human_name,
        replier=ollama_replier(args.ollama_host, args.ollama_model),
        publish=publish,
        # The tutorial's robots ask the server which shared event an utterance is (created/matched/ambiguous).
        shared_event_resolver=HTTPSharedContextResolver(base_url=server, token=args.token),
    )
    print(f"{'start':<24} {'robot':<10} {config.robot_name} meets {script.human_name}  {_published(last)}")
    if last.get("triples_new") == 0:
        print(_already_there(config.robot_name, script.human_name), file=sys.stderr, flush=True)
    for step in play(mission, script):
        source = f" [{step.reply_source}]" if step.reply_source else ""
        when = step.at.isoformat(timespec="milliseconds").replace("+00:00", "Z")
        print(f"{when:<24} {step.kind:<10} {step.description}{source}  {_published(last)}", flush=True)


def _config(model: str) -> RobotConfig:
    config = RobotConfig()
    if model == config.llm_label:
        return config
    # Another Ollama model: log its name, and its tag as the version ("qwen2.5:3b" -> "3b").
    return replace(config, llm_label=model, llm_version=model.partition(":")[2] or "latest")


def _published(response: dict[str, Any]) -> str:
    received = response.get("triples_received", "?")
    return f"-> {response.get('triples_new', '?')} new of {received} {'triple' if received == 1 else 'triples'}"


def _already_there(robot: str, human: str) -> str:
    """The start (robot, person, models) has fixed IRIs: when none of it is new, this visit was logged before."""
    return (
        f"emotion_mirror: warning: the server already holds {robot}'s log with {human}. Replaying the script again "
        "adds every emotion reading and state snapshot a second time (the client gives them new IRIs), so the "
        "emotion timeline will show each reading twice. Clear the graph first for a clean run "
        "(the UI's /logs/delete page, or POST /ttl/delete_all)."
    )


def _unreachable(server: str) -> str | None:
    """Why the server cannot be used, or None. Checked once up front so a typo fails before any work."""
    try:
        response = httpx.get(f"{server}/healthz/live", timeout=3)
    except (httpx.HTTPError, httpx.InvalidURL) as error:
        return str(error) or type(error).__name__
    return None if response.status_code == 200 else f"HTTP {response.status_code} from /healthz/live"


def _fail(message: str, status: int = 1) -> int:
    print(f"emotion_mirror: error: {message}", file=sys.stderr)
    return status


if __name__ == "__main__":
    sys.exit(main())
