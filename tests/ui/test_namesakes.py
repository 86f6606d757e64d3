"""Things that share a label are told apart wherever they are shown: the demo's Maria (logged by ARI) and the
example robot's Maria, and the face model three robots registered under one name."""

from __future__ import annotations

from typing import Any

import httpx
import pytest

from tests.conftest import UiStack

pytestmark = pytest.mark.browser


def test_filters_and_tables_tell_the_two_marias_apart_by_who_met_them(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    page.goto(f"{demo_stack.ui_url}/reports")
    humans = page.locator("select[name=human] option").all_inner_texts()
    assert len(humans) == len(set(humans))
    assert "Maria (ARI, TIAGo)" in humans and "Maria (Emotion Mirror)" in humans
    assert "Carlos" in humans  # a name nobody else has stays as it is

    shown = page.locator("#report-participants tbody tr td:first-child").all_inner_texts()
    assert sorted(set(shown)) == ["Carlos", "Maria (ARI, TIAGo)", "Maria (Emotion Mirror)"]
    charts = page.locator("#report-emotion-timeline figcaption").all_inner_texts()
    assert len(charts) == len(set(charts))
    assert "Maria (Emotion Mirror) (human)" in charts

    page.select_option("select[name=human]", label="Maria (Emotion Mirror)")
    page.click("form.filters button[type=submit]")
    page.wait_for_load_state()
    pairs = page.locator("#report-participants tbody tr").all_inner_texts()
    assert len(pairs) == 1 and "Emotion Mirror" in pairs[0]


def test_the_model_usage_chart_names_the_robots_that_used_each_model(demo_stack: UiStack, open_at: Any) -> None:
    page = open_at("desktop")
    page.goto(f"{demo_stack.ui_url}/reports/ml-usage")
    bars = page.locator("svg.bar-chart g.bar text title").all_text_contents()
    assert sorted(bars) == [
        "Emotion Big6 CNN 1.0 (ARI)",
        "Emotion Big6 CNN 1.0 (Emotion Mirror)",
        "Emotion Big6 CNN 1.0 (TIAGo)",
    ]
    models = page.locator("#report-ml-usage tbody tr td:nth-child(2)").all_inner_texts()
    assert set(models) == {"Emotion Big6 CNN (ARI)", "Emotion Big6 CNN (Emotion Mirror)", "Emotion Big6 CNN (TIAGo)"}


def test_the_graph_labels_namesakes_apart(demo_stack: UiStack) -> None:
    drawn = httpx.get(f"{demo_stack.ui_url}/kg-graph/data", timeout=30).json()
    humans = sorted(node["label"] for node in drawn["nodes"] if node["kind"] == "human")
    assert humans == ["Carlos", "Maria (ARI, TIAGo)", "Maria (Emotion Mirror)"]  # the robots that met each
    messages = [node["label"] for node in drawn["nodes"] if node["kind"] == "message"]
    assert "I am here with you. Tell me more." in messages  # repeated words are not namesakes
