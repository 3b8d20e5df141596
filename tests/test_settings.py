"""Settings come from PHONGRAY_* variables through pydantic-settings, and a wrong one is one line."""

import pytest
from pydantic_settings import BaseSettings

from service.cli import parse
from service.settings import Settings, SettingsError


def test_settings_are_read_from_the_environment_with_their_types(monkeypatch):
    monkeypatch.setenv("PHONGRAY_MAX_PIXELS", "1000")
    monkeypatch.setenv("PHONGRAY_RENDER_TIMEOUT", "2.5")
    monkeypatch.setenv("PHONGRAY_API_KEY", "k")
    settings = Settings.from_env()
    assert isinstance(settings, BaseSettings)
    assert (settings.max_pixels, settings.render_timeout, settings.api_key) == (1000, 2.5, "k")
    assert Settings(max_cost=5).max_cost == 5  # explicit values win


def test_a_wrong_value_names_its_variable(monkeypatch):
    monkeypatch.setenv("PHONGRAY_MAX_PIXELS", "lots")
    with pytest.raises(SettingsError) as info:
        Settings.from_env()
    said = str(info.value)
    assert said.startswith("PHONGRAY_MAX_PIXELS: Input should be a valid integer") and "'lots'" in said


def test_the_command_lines_defaults_come_from_the_settings(monkeypatch):
    monkeypatch.setenv("PHONGRAY_CLUSTER", "tcp://127.0.0.1:8786")
    monkeypatch.setenv("PHONGRAY_CLUSTER_WAIT", "5")
    args = parse(["grade-class", "s", "u", "-o", "r"])
    assert (args.cluster, args.cluster_wait) == ("tcp://127.0.0.1:8786", 5.0)
    monkeypatch.delenv("PHONGRAY_CLUSTER")
    monkeypatch.delenv("PHONGRAY_CLUSTER_WAIT")
    args = parse(["render", "s.json", "-o", "x.png"])
    assert (args.cluster, args.cluster_wait) == (None, 30.0)
