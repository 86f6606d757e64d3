"""Where the robot's replies come from: a local Ollama model when one is there, else the fixed fallback.

The mission logs the source of every reply (`reply_source`, "ollama" or "fallback"), so an auditor can
tell generated replies from canned ones. The `ollama` package is optional: it is imported only here,
only when a server answers, and the project does not depend on it.
"""

from __future__ import annotations

import logging
import os
from typing import Any

import httpx

from segb_server.examples.emotion_mirror.mission import Replier, fallback_replier

DEFAULT_HOST = "http://127.0.0.1:11434"
DEFAULT_MODEL = "llama3.2"
PROBE_TIMEOUT_SECONDS = 0.5
SYSTEM_PROMPT = "You are a friendly social robot. Answer in one or two short, warm sentences."

logger = logging.getLogger("emotion_mirror.replier")


def ollama_replier(host: str | None = None, model: str = DEFAULT_MODEL) -> Replier:
    """A replier backed by Ollama at `host` (default: OLLAMA_HOST, else 127.0.0.1:11434), or the fallback.

    Falls back when the `ollama` package is missing or no server answers a quick probe, and, per reply,
    when the model call fails: the robot must keep talking, and the log then says "fallback".
    """
    url = server_url(host or os.environ.get("OLLAMA_HOST") or DEFAULT_HOST)
    try:
        import ollama  # optional: never a dependency of the project
    except ImportError:
        logger.info("the ollama package is not installed: replies use the fixed fallback")
        return fallback_replier
    if not answers(url):
        logger.info("no Ollama server answers at %s: replies use the fixed fallback", url)
        return fallback_replier
    client = ollama.Client(host=url)

    def reply(text: str) -> tuple[str, str]:
        try:
            response: Any = client.chat(
                model=model,
                messages=[{"role": "system", "content": SYSTEM_PROMPT}, {"role": "user", "content": text}],
            )
            content = str(response["message"]["content"]).strip()
        except Exception as error:  # any client or server failure: the conversation goes on
            logger.warning("Ollama %s failed (%s): fixed fallback used for this reply", model, error)
            return fallback_replier(text)
        return (content, "ollama") if content else fallback_replier(text)

    return reply


def server_url(host: str) -> str:
    """OLLAMA_HOST may be given as `host:port` without a scheme, as the Ollama CLI accepts it."""
    host = host.strip().rstrip("/")
    return host if host.startswith(("http://", "https://")) else f"http://{host}"


def answers(url: str) -> bool:
    """True when an Ollama server replies to its version endpoint within the probe timeout."""
    try:
        return httpx.get(f"{url}/api/version", timeout=PROBE_TIMEOUT_SECONDS).status_code == 200
    except httpx.HTTPError:
        return False
