"""Random robot histories that touch every audit rule, for the findings' differential tests: human messages and
replies (on time, late, never), replies with and without a model, emotions read and expressed (strong, out of
range, mirrored or not), and the data-quality slips (no start, a time that is no date, a message without text,
an untyped subject, a model without a version). Each part of a unit may arrive in a later post."""

from __future__ import annotations

from dataclasses import dataclass

from tests.support.histories import EX, HUMANS, ROBOTS, History, iri, term

EMOML = "http://www.gsi.upm.es/ontologies/onyx/vocabularies/emotionml/ns#"


def at(seconds: float, offset_hours: int = 0) -> str:
    """The instant `seconds` after 09:00 UTC, written in UTC or (`offset_hours`) in another zone's clock."""
    whole = int(seconds)
    fraction = f".{round((seconds - whole) * 1000):03d}" if seconds != whole else ""
    zone = f"+{offset_hours:02d}:00" if offset_hours else "Z"
    clock = f"{9 + offset_hours:02d}:{whole // 60 % 60:02d}:{whole % 60:02d}{fraction}"
    return f'"2026-03-10T{clock}{zone}"^^{term("xsd:dateTime")}'


@dataclass
class RuleHistory(History):
    """A `History` (posts, late parts, re-publishes, clearings) whose units touch every audit rule."""

    def base(self) -> list[str]:
        triples = []
        for robot in ROBOTS:
            triples += [
                f"{iri('robot', robot)} {term('rdf:type')} {term('oro:Robot')} .",
                f'{iri("robot", robot)} {term("schema:name")} "{robot.upper()}" .',
            ]
        for human in HUMANS:
            triples += [
                f"{iri('human', human)} {term('rdf:type')} {term('oro:Human')} .",
                f'{iri("human", human)} {term("foaf:firstName")} "{human.capitalize()}" .',
            ]
        triples += [
            f"{iri('model', 'llm')} {term('rdf:type')} {term('mls:Model')} .",
            f'{iri("model", "llm")} <http://schema.org/version> "3.2" .',
            f"{iri('model', 'bare')} {term('rdf:type')} {term('mls:Model')} .",  # no version
        ]
        return triples

    def unit(self) -> list[list[str]]:
        """One exchange: an emotion read, a human's message, maybe a reply (late or not), maybe an expression."""
        self.counter += 1
        n, rng = self.counter, self.rng
        robot, human = iri("robot", rng.choice(ROBOTS)), iri("human", rng.choice(HUMANS))
        start = rng.randrange(0, 3000)
        event = iri("event", f"e{n}")
        read, listen, reply = iri("activity", f"read{n}"), iri("activity", f"listen{n}"), iri("activity", f"reply{n}")
        heard, said = iri("message", f"heard{n}"), iri("message", f"said{n}")
        t = term
        parts: list[list[str]] = []
        category = f"<{EMOML}big6_{rng.choice(['sadness', 'anger', 'happiness', 'fear'])}>"
        intensity = rng.choice(["0.4", "0.8", "0.95", "1.4"])
        reading = [
            f"{read} {t('rdf:type')} {t('segb:LoggedActivity')} .",
            f"{read} {t('segb:wasPerformedBy')} {robot} .",
            f"{read} {t('segb:producedEntityResult')} {iri('annotation', f'r{n}')} .",
            f"{iri('annotation', f'r{n}')} {t('oa:hasTarget')} {human} .",
            f"{iri('annotation', f'r{n}')} {t('onyx:hasEmotion')} {iri('emotion', f'r{n}')} .",
            f"{iri('emotion', f'r{n}')} {t('rdf:type')} {t('onyx:Emotion')} .",
            f"{iri('emotion', f'r{n}')} {t('onyx:hasEmotionCategory')} {category} .",
            f'{iri("emotion", f"r{n}")} {t("onyx:hasEmotionIntensity")} "{intensity}"^^{t("xsd:float")} .',
        ]
        parts.append(reading)
        time_value = at(start) if rng.random() < 0.9 else f'"ten past nine"^^{t("xsd:string")}'
        parts.append([f"{read} {t('prov:startedAtTime')} {time_value} ."])  # may come late: a missing time
        parts.append([f"{event} {t('rdf:type')} {t('schema:Event')} .", f"{event} {t('schema:about')} {human} ."])
        listening = [
            f"{listen} {t('rdf:type')} {t('segb:LoggedActivity')} .",
            f"{heard} {t('rdf:type')} {t('schema:Message')} .",
            f"{heard} {t('rdf:type')} {t('oro:InitialMessage')} .",
            f"{heard} {t('schema:sender')} {human} .",
            f"{heard} {t('prov:wasAttributedTo')} {human} .",  # as the PyPI client attributes a message
            f"{heard} {t('prov:wasGeneratedBy')} {listen} .",
        ]
        parts.append(listening)
        # Which robot listened may come late: the robot of a finding about what it heard is that robot.
        parts.append([f"{listen} {t('segb:wasPerformedBy')} {robot} ."])
        parts.append([f"{listen} {t('prov:startedAtTime')} {at(start + 1)} ."])  # a late or missing time
        if rng.random() < 0.85:
            parts.append([f'{heard} {t("schema:text")} "said {n}"@en .'])  # a message may have no text
        if rng.random() < 0.75:  # answered (on time or late), else never
            delay = rng.choice([1.5, 4, 12.25, 30])
            parts.append(
                [
                    f"{reply} {t('rdf:type')} {t('segb:LoggedActivity')} .",
                    f"{reply} {t('rdf:type')} {t('oro:ResponseAction')} .",
                    f"{reply} {t('segb:wasPerformedBy')} {robot} .",
                    f"{reply} {t('schema:about')} {event} .",
                    f"{reply} {t('segb:triggeredByEntity')} {heard} .",
                    f"{said} {t('rdf:type')} {t('schema:Message')} .",
                    f'{said} {t("schema:text")} "reply {n}"@en .',
                    f"{said} {t('prov:wasGeneratedBy')} {reply} .",
                ]
            )
            parts.append([f"{said} {t('prov:wasDerivedFrom')} {heard} ."])  # the link may come late
            # A robot may write its local time: the same instant an hour ahead, in a zone of +01:00.
            offset = rng.choice([0, 0, 1])
            parts.append([f"{reply} {t('prov:startedAtTime')} {at(start + 1 + delay, offset)} ."])
            if rng.random() < 0.5:
                model = iri("model", rng.choice(["llm", "bare"]))
                parts.append([f"{reply} {t('segb:usedMLModel')} {model} ."])
            if rng.random() < 0.6:  # the robot expresses an emotion, triggered by what it read
                shown = f"<{EMOML}big6_{rng.choice(['sadness', 'happiness'])}>"
                parts.append(
                    [
                        f"{reply} {t('segb:triggeredByActivity')} {read} .",
                        f"{reply} {t('segb:producedEntityResult')} {iri('annotation', f'x{n}')} .",
                        f"{iri('annotation', f'x{n}')} {t('oa:hasTarget')} {robot} .",
                        f"{iri('annotation', f'x{n}')} {t('onyx:hasEmotion')} {iri('emotion', f'x{n}')} .",
                        f"{iri('emotion', f'x{n}')} {t('onyx:hasEmotionCategory')} {shown} .",
                        f'{iri("emotion", f"x{n}")} {t("onyx:hasEmotionIntensity")} "0.7"^^{t("xsd:float")} .',
                    ]
                )
        if rng.random() < 0.2:  # something the log says of an untyped resource
            parts.append([f"{iri('note', f'n{n}')} {t('prov:wasInfluencedBy')} {read} ."])
            if rng.random() < 0.5:
                parts.append([f"{iri('note', f'n{n}')} {t('rdf:type')} {t('prov:Entity')} ."])
        return parts


__all__ = ["EX", "RuleHistory"]
