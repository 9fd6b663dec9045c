"""Network config: validation of profiles, outages and overrides; link names; profile resolution."""

import math
from typing import Any

import pytest

from common.config.network import (
    LinkOverride,
    LinkProfile,
    NetworkConfig,
    Outage,
    link_matches,
    link_name,
    parse_link,
    profile_for,
)


def test_default_profile_is_an_ideal_link() -> None:
    p = LinkProfile()
    assert (p.delay_s, p.jitter, p.loss, p.duplicate_p, p.fifo, p.bandwidth_bps) == (
        0.0,
        "none",
        "none",
        0.0,
        True,
        0.0,
    )


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"delay_s": -0.1}, "delay_s"),
        ({"delay_s": math.inf}, "delay_s"),
        ({"jitter": "normal", "jitter_s": -1.0}, "jitter_s"),
        ({"jitter": "gauss", "jitter_s": 1.0}, "jitter"),
        ({"jitter_s": 0.1}, "jitter_s"),  # jitter 'none' with a scale
        ({"jitter": "uniform", "jitter_s": 0.2, "delay_s": 0.1}, "jitter_s"),
        ({"jitter": "pareto", "jitter_s": 0.1, "pareto_shape": 2.0}, "pareto_shape"),
        ({"jitter": "normal", "jitter_s": 0.1, "trace_file": "x.csv"}, "jitter"),
        ({"loss": "bernoulli", "loss_p": 1.5}, "loss_p"),
        ({"loss_p": 0.1}, "loss_p"),  # loss 'none' with a probability
        ({"loss": "burst"}, "loss"),
        ({"ge_p_gb": -0.1}, "ge_p_gb"),
        ({"ge_loss_bad": 1.1}, "ge_loss_bad"),
        ({"loss": "gilbert_elliott", "ge_p_gb": 0.0, "ge_p_bg": 0.0}, "ge_p_bg"),
        ({"duplicate_p": 2.0}, "duplicate_p"),
        ({"bandwidth_bps": -1.0}, "bandwidth_bps"),
        ({"queue_len": 0}, "queue_len"),
    ],
)
def test_profile_rejects_bad_values_naming_the_field(kwargs: dict[str, Any], field: str) -> None:
    with pytest.raises(ValueError, match=f"^{field}:"):
        LinkProfile(**kwargs)


def test_link_names_round_trip_and_reject_bad_parts() -> None:
    name = link_name("sensor", "nav", "estimator")
    assert name == "sensor/nav->estimator"
    assert parse_link(name) == ("sensor", "nav", "estimator")
    for bad in (("sen/sor", "nav", "x"), ("sensor", "nav", "*"), ("", "nav", "x")):
        with pytest.raises(ValueError, match="^link:"):
            link_name(*bad)


def test_link_patterns() -> None:
    link = "planner/cmd->vehicle"
    assert link_matches(link, link)
    assert link_matches("planner/cmd->*", link)
    assert link_matches("*->vehicle", link)
    assert not link_matches("planner/path->*", link)
    assert not link_matches("*->planner", link)
    assert not link_matches("sensor/nav->vehicle", link)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"start_s": 1.0, "end_s": 1.0, "link": "a/b->c"}, "end_s"),
        ({"start_s": -1.0, "end_s": 1.0, "link": "a/b->c"}, "start_s"),
        ({"start_s": 0.0, "end_s": 1.0}, "link"),
        ({"start_s": 0.0, "end_s": 1.0, "link": "a/b->c", "service": "a"}, "link"),
        ({"start_s": 0.0, "end_s": 1.0, "link": "a->c"}, "link"),
        ({"start_s": 0.0, "end_s": 1.0, "service": "a/b"}, "service"),
    ],
)
def test_outage_validation(kwargs: dict[str, Any], field: str) -> None:
    with pytest.raises(ValueError, match=f"^{field}:"):
        Outage(**kwargs)


def test_outage_applies_by_link_pattern_or_service() -> None:
    by_service = Outage(start_s=0.0, end_s=math.inf, service="planner")
    assert by_service.applies_to("planner/cmd->vehicle")  # as sender
    assert by_service.applies_to("sensor/nav->planner")  # as receiver
    assert not by_service.applies_to("sensor/nav->estimator")
    by_link = Outage(start_s=0.0, end_s=1.0, link="sensor/nav->*")
    assert by_link.applies_to("sensor/nav->planner")
    assert not by_link.applies_to("sensor/obstacles->planner")


def test_profile_for_prefers_exact_then_stream_then_receiver_then_default() -> None:
    exact = LinkProfile(delay_s=0.1)
    stream = LinkProfile(delay_s=0.2)
    recv = LinkProfile(delay_s=0.3)
    cfg = NetworkConfig(
        default=LinkProfile(delay_s=0.4),
        links=(
            LinkOverride(link="*->vehicle", profile=recv),
            LinkOverride(link="planner/cmd->*", profile=stream),
            LinkOverride(link="planner/cmd->vehicle", profile=exact),
        ),
    )
    assert profile_for(cfg, "planner/cmd->vehicle") is exact
    assert profile_for(cfg, "planner/cmd->monitor") is stream
    assert profile_for(cfg, "sensor/nav->vehicle") is recv
    assert profile_for(cfg, "sensor/nav->estimator") is cfg.default


def test_network_config_rejects_duplicate_and_malformed_overrides() -> None:
    o = LinkOverride(link="a/b->c", profile=LinkProfile())
    with pytest.raises(ValueError, match="^links:"):
        NetworkConfig(links=(o, o))
    with pytest.raises(ValueError, match="^link:"):
        LinkOverride(link="*->*", profile=LinkProfile())
