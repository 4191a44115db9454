import numpy as np
import pytest

import stewart_env as se


@pytest.fixture(scope="session")
def dasgupta():
    return se.load_platform("dasgupta1998")


@pytest.fixture(scope="session")
def simulator():
    return se.load_platform("motion_simulator")


@pytest.fixture
def rng():
    return np.random.default_rng(20180523)


@pytest.fixture
def headless(monkeypatch):
    """No display, as on CI and servers: human rendering must warn once and draw nothing."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
