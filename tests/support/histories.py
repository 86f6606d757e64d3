"""Random robot histories in the client's shapes, for differential tests of the views kept current from the
journal: several robots, links arriving late, out-of-order times, re-publishes and clearings."""

from __future__ import annotations

import random
from dataclasses import dataclass, field

from tests.support.in_process import Server, http

EX = "https://example.org/diff/"
P = {
    "rdf": "http://www.w3.org/1999/02/22-rdf-syntax-ns#", "rdfs": "http://www.w3.org/2000/01/rdf-schema#",
    "prov": "http://www.w3.org/ns/prov#", "foaf": "http://xmlns.com/foaf/0.1/", "schema": "http://schema.org/",
    "oa": "http://www.w3.org/ns/oa#", "segb": "http://www.gsi.upm.es/ontologies/segb/ns#",
    "oro": "http://kb.openrobots.org#", "onyx": "http://www.gsi.upm.es/ontologies/onyx/ns#",
    "mls": "http://www.w3.org/ns/mls#", "xsd": "http://www.w3.org/2001/XMLSchema#",
}  # fmt: skip
ROBOTS = ["ari", "tiago"]
HUMANS = ["maria", "juan", "carlos"]


def iri(kind: str, name: str) -> str:
    return f"<{EX}{kind}/{name}>"


def term(prefixed: str) -> str:
    prefix, local = prefixed.split(":", 1)
    return f"<{P[prefix]}{local}>"


def time_literal(seconds: int) -> str:
    return f'"2026-03-10T09:{seconds // 60 % 60:02d}:{seconds % 60:02d}Z"^^{term("xsd:dateTime")}'


@dataclass
class History:
    """Random robot logs in the client's shapes; each part of a unit of activity may arrive in a later post."""

    seed: int
    robots: tuple[str, ...] = tuple(ROBOTS)  # one robot and one person: the hubs whose history grows
    humans: tuple[str, ...] = tuple(HUMANS)
    rng: random.Random = field(init=False)
    pending: list[list[str]] = field(default_factory=list)  # triples held back: late links
    sent: list[str] = field(default_factory=list)
    counter: int = 0

    def __post_init__(self) -> None:
        self.rng = random.Random(self.seed)

    def base(self) -> list[str]:
        triples = []
        for robot in self.robots:
            triples += [f"{iri('robot', robot)} {term('rdf:type')} {term('oro:Robot')} ."]
            if self.rng.random() < 0.8:  # a robot's name may come late
                triples.append(f'{iri("robot", robot)} {term("schema:name")} "{robot.upper()}" .')
        for human in self.humans:
            triples += [
                f"{iri('human', human)} {term('rdf:type')} {term('oro:Human')} .",
                f'{iri("human", human)} {term("foaf:firstName")} "{human.capitalize()}" .',
            ]
        for model in ("cnn", "llm"):
            triples += [
                f"{iri('model', model)} {term('rdf:type')} {term('mls:Model')} .",
                f'{iri("model", model)} {term("rdfs:label")} "{model.upper()}" .',
            ]
        return triples

    def unit(self) -> list[list[str]]:
        """One interaction, split in parts that may be sent in different posts."""
        self.counter += 1
        n, rng = self.counter, self.rng
        robot, human = rng.choice(self.robots), rng.choice(self.humans)
        activity, message = iri("activity", f"a{n}"), iri("message", f"m{n}")
        event = iri("event", f"e{rng.randrange(max(1, n // 2) + 1)}")  # events shared by several activities
        seconds = rng.randrange(0, 3600)  # out-of-order times
        core = [
            f"{activity} {term('rdf:type')} {term('segb:LoggedActivity')} .",
            f"{activity} {term('prov:startedAtTime')} {time_literal(seconds)} .",
            f'{message} {term("schema:text")} "said {n}"@en .',
            f"{message} {term('prov:wasGeneratedBy')} {activity} .",
        ]
        # Mostly with its message; else apart, so that it may come late (until then an observation, not a message)
        message_type = [f"{message} {term('rdf:type')} {term('schema:Message')} ."]
        if rng.random() < 0.8:
            core, message_type = core + message_type, []
        performed = [f"{activity} {term('segb:wasPerformedBy')} {iri('robot', robot)} ."]
        shared = [
            f"{activity} {term('schema:about')} {event} .",
            f"{event} {term('rdf:type')} {term('schema:Event')} .",
            f"{event} {term('schema:about')} {iri('human', human)} .",
        ]
        # What tells who spoke may come late: the activity's kind, the message's type, a sender (a human, the
        # robot, or none).
        kinds = rng.choices(
            ["oro:ListeningEvent", "oro:ResponseAction", "oro:DetectedHumanEvent", "oro:EmotionRecognitionEvent"],
            weights=[4, 4, 1, 1],
        )
        if rng.random() < 0.15:
            kinds.append("oro:DetectedHumanEvent")  # of two kinds: the most specific is its timeline's
        kind = [f"{activity} {term('rdf:type')} {term(name)} ." for name in dict.fromkeys(kinds)]
        typed = [f"{message} {term('rdf:type')} {term('oro:InitialMessage')} ."] if rng.random() < 0.3 else []
        speaker = rng.choices([iri("human", human), iri("robot", robot), None], weights=[5, 2, 3])[0]
        sender = [f"{message} {term('schema:sender')} {speaker} ."] if speaker else []
        model = [f"{activity} {term('segb:usedMLModel')} {iri('model', rng.choice(['cnn', 'llm']))} ."]
        annotation, emotion = iri("annotation", f"n{n}"), iri("emotion", f"x{n}")
        target = iri("human", human) if rng.random() < 0.7 else iri("robot", robot)
        category = term("onyx:" + rng.choice(["joy", "anger"]))
        intensity = f'"{rng.choice(["0.2", "0.8", "0.95"])}"^^{term("xsd:decimal")}'
        feeling = [
            f"{activity} {term('segb:producedEntityResult')} {annotation} .",
            f"{annotation} {term('onyx:hasEmotion')} {emotion} .",
            f"{annotation} {term('oa:hasTarget')} {target} .",
            f"{emotion} {term('onyx:hasEmotionCategory')} {category} .",
            f"{emotion} {term('onyx:hasEmotionIntensity')} {intensity} .",
        ]
        state = iri("state", f"s{n}")
        snapshot = [
            f"{state} {term('prov:wasAttributedTo')} {iri('robot', robot)} .",
            f"{state} {term('prov:generatedAtTime')} {time_literal(seconds)} .",
            f'{state} {term("rdfs:comment")} "note {n}" .',
        ]
        parts = [core, message_type, performed, kind, typed, shared, sender, model, feeling]
        if rng.random() < 0.3:
            parts.append(snapshot)
        return [part for part in parts if part]

    def backlog(self, units: int) -> list[str]:
        """A history's past in one post: `units` interactions whole, with the base (no late links)."""
        post = self.base() if not self.sent else []
        for _ in range(units):
            post += [triple for part in self.unit() for triple in part]
        self.sent += post
        return post

    def next_post(self) -> list[str] | None:
        """The triples of the next post, or None for a clearing."""
        roll = self.rng.random()
        if roll < 0.05:
            self.pending = []
            return None
        post: list[str] = []
        if not self.sent or roll < 0.15:
            post += self.base()
        for part in self.unit():
            if self.rng.random() < 0.35:
                self.pending.append(part)  # sent in a later post: a late link
            else:
                post += part
        while self.pending and self.rng.random() < 0.5:
            post += self.pending.pop(self.rng.randrange(len(self.pending)))
        if self.sent and self.rng.random() < 0.3:
            post += self.rng.sample(self.sent, min(len(self.sent), 20))  # re-published
        self.sent += post
        return post


def send(server: Server, post: list[str] | None) -> None:
    """A post of a history to `server` (N-Triples), or, for None, a clearing of the graph."""
    if post is None:
        answer = http(server, "POST", "/ttl/delete_all", json={})
        assert answer.status_code == 200, answer.text
        return
    answer = http(server, "POST", "/ttl", content="\n".join(post), headers={"Content-Type": "application/n-triples"})
    assert answer.status_code == 201, answer.text
