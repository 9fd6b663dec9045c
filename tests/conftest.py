"""Shared fixtures (scenario files for the runtime self-test loop, certificates), and the
hook that groups tests on pytest-xdist workers (exclusive ones; a module fixture's)."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest
from helpers import testloop
from helpers.runs import CACHE_ENV

ROOT = Path(__file__).resolve().parents[1]

# A network profile with everything the acceptance asks for: delay, jitter, Bernoulli and
# Gilbert-Elliott loss, duplication and an outage.
LOSSY_TESTLOOP = """
[run]
mission = "testloop"
max_time_s = {max_time}

[network.default]
delay_s = 0.05
jitter = "normal"
jitter_s = 0.03
loss = "bernoulli"
loss_p = 0.1
duplicate_p = 0.05
fifo = false

[[network.links]]
link = "ctrl/cmd->plant"
[network.links.profile]
delay_s = 0.08
jitter = "exponential"
jitter_s = 0.02
loss = "gilbert_elliott"
ge_p_gb = 0.05
ge_p_bg = 0.3

[[network.outages]]
start_s = 4.0
end_s = 5.5
service = "filter"
"""


@pytest.fixture
def testloop_toml(tmp_path: Path) -> Path:
    p = tmp_path / "testloop.toml"
    p.write_text(LOSSY_TESTLOOP.format(max_time=10.0))
    return p


@pytest.fixture(scope="session")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A certificates directory of every default identity (`tidelink certs`), shared by the
    session's tests: its CA signs them all; router certificates also name the netns hosts'
    router addresses (10.201.<i>.1, tests/test_netns_launch.py)."""
    from common.bus.certs import DEFAULT_IDENTITIES, create_certs, default_hosts

    directory = tmp_path_factory.mktemp("certs")
    hosts = [*default_hosts(), *(f"10.201.{i}.1" for i in range(1, 5))]
    create_certs(directory, DEFAULT_IDENTITIES, hosts=hosts)
    return directory


@pytest.fixture(scope="session")
def other_certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Certificates of the same names from another CA (a stranger's)."""
    from common.bus.certs import DEFAULT_IDENTITIES, create_certs

    directory = tmp_path_factory.mktemp("other-certs")
    create_certs(directory, DEFAULT_IDENTITIES)
    return directory


def pytest_configure(config: pytest.Config) -> None:
    """The session's test mission, `testloop`, registered in the environment
    (TIDELINK_MISSIONS, common/config/missions.py), so every process the tests start knows it
    too; and the session's cache of inproc reference runs (helpers/runs.py), made by the
    controlling process before pytest-xdist starts its workers, which inherit both variables."""
    session = pytest.MonkeyPatch()
    session.setenv(*testloop.missions_env(os.environ))
    config.add_cleanup(session.undo)
    if not hasattr(config, "workerinput") and CACHE_ENV not in os.environ:
        os.environ[CACHE_ENV] = tempfile.mkdtemp(prefix="tidelink-test-runs-")
        config.add_cleanup(lambda: shutil.rmtree(os.environ.pop(CACHE_ENV), ignore_errors=True))


# first: pytest-xdist reads the groups in its own hook of the same name
@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """xdist groups (`--dist loadgroup`, as scripts/test runs them): the tests marked
    exclusive form one group, so they run one after another on one worker while the others
    take the lighter wall-clock tests; the tests sharing a module-scoped fixture form one, so
    the fixture (a whole launch, a sweep) runs once, not once per worker that runs one.

    The longest work goes first (the exclusive group, then the multi-process and heavy
    tests), so that no worker is left with a long test while the others have finished."""
    for item in items:
        if item.get_closest_marker("exclusive") is not None:
            item.add_marker(pytest.mark.xdist_group("exclusive"))
            continue
        info = getattr(item, "_fixtureinfo", None)
        if info is None:
            continue
        for name in info.names_closure:
            defs = info.name2fixturedefs.get(name)
            if defs and defs[-1].scope == "module":
                item.add_marker(pytest.mark.xdist_group(f"{item.path.stem}.{name}"))
                break
    items.sort(key=_order)


def _order(item: pytest.Item) -> int:
    for rank, mark in enumerate(("exclusive", "background", "heavy", "slow")):
        if item.get_closest_marker(mark) is not None:
            return rank
    return 4
