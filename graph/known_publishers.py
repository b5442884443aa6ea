"""Known publishers: which announced publishers a subscription takes messages from.

ROS 2 lets anybody publish on any topic. For a configuration topic that is one node's to say (the projector's
PatternSequence, the camera's CameraInfo) or a topic whose messages end a run (the scan statuses a monitor
counts), one more publisher is a fault: one forged PatternSequence with the opposite shift sign gave hundreds
of scans reported "ok" with wrong clouds. A subscription made with ``publishers=KnownPublishers(...)`` is
connected only to the publishers the policy accepts, decided from the graph's announcements (discovery) before
any socket connects, so a refused publisher's messages never arrive. Each refusal is logged once per publisher.

Policy (:class:`KnownPublishers`):

- ``nodes``: fully qualified node names whose publishers are taken (relative names are resolved in the
  subscribing node's namespace by ``Node.create_subscription``); empty = any node.
- Two live nodes of one name: the older (announced start time, then pid) is the node of that name; the
  other is refused as a conflicting second publisher.
- ``sole``: one publishing node at most: the one the subscription is connected to already, else the node of the
  oldest publisher (its announced ``created_time``, then the node's start time); every other is refused while
  it lives. When it goes away, the next oldest takes over (a respawned owner is found like any publisher).

Limits (docs/reliability.md): the oldest publisher wins when nothing is connected yet, so a stranger that
published before a respawned owner keeps the topic (for the subscriptions that start then) until it leaves;
and on ipc any process of the same user can announce anything. What this guards against is a second
publisher, by mistake or from a participant that joined the graph, not the user's own code.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

__all__ = ["SECOND_GRAPH_ADVICE", "KnownPublishers", "SOLE_PUBLISHER", "select_publishers"]

#: What a refusal of a second node of one name says to do: two nodes of one name are most often two graphs
#: started in one domain, whose messages would mix (one graph's monitor counting the other's scans).
SECOND_GRAPH_ADVICE = ("Two graphs in one domain? Run each in its own domain (DPTPU_DOMAIN_ID=N in its environment, "
                       "or dptpu launch --domain-id N); or give one of the nodes another name or namespace")


@dataclass(frozen=True)
class KnownPublishers:
    """Which publishers a subscription accepts (see the module docstring).

    Parameters
    ----------
    nodes : tuple of str
        Fully qualified names of the nodes whose publishers are taken; empty: any node.
    sole : bool
        Take one publishing node only, the oldest.
    """

    nodes: tuple[str, ...] = ()
    sole: bool = False

    def __post_init__(self):
        if isinstance(self.nodes, str):
            raise ValueError(f"KnownPublishers.nodes must be a tuple of node names; got the string {self.nodes!r}")
        object.__setattr__(self, "nodes", tuple(self.nodes))


#: A configuration topic: the oldest publishing node only.
SOLE_PUBLISHER = KnownPublishers(sole=True)


def _age_key(entry: dict) -> tuple:
    start = entry.get("start_time")
    pid = entry.get("pid")
    return (float(start) if isinstance(start, (int, float)) else float("inf"),
            int(pid) if isinstance(pid, int) else 0, str(entry.get("gid", "")))


def _publisher_age_key(pair: tuple) -> tuple:
    entry, pub = pair
    created = pub.get("created_time")
    return (float(created) if isinstance(created, (int, float)) else float("inf"), *_age_key(entry))


def select_publishers(candidates: list, policy: KnownPublishers | None,
                      connected: Collection[str] = ()) -> tuple[list, list]:
    """``(accepted, refused)`` of ``candidates``, the ``(entry, publisher)`` pairs of one topic.

    ``connected``: gids (hex) of the publishers the subscription is connected to now. ``refused`` holds
    ``(entry, publisher, reason)``; with ``policy`` None everything is accepted.
    """
    if policy is None or not candidates:
        return list(candidates), []
    accepted: list = []
    refused: list = []
    oldest_of_name: dict[str, dict] = {}
    for entry, _pub in candidates:
        name = str(entry.get("fqn"))
        if name not in oldest_of_name or _age_key(entry) < _age_key(oldest_of_name[name]):
            oldest_of_name[name] = entry
    for entry, pub in candidates:
        name = str(entry.get("fqn"))
        if policy.nodes and name not in policy.nodes:
            taken = ", ".join(policy.nodes)
            refused.append((entry, pub, f"node {name} is not among the publishers it takes ({taken})"))
        elif oldest_of_name[name] is not entry:
            refused.append((entry, pub, f"a second node named {name} (pid {entry.get('pid')}); the one of pid "
                                        f"{oldest_of_name[name].get('pid')} is older. {SECOND_GRAPH_ADVICE}"))
        else:
            accepted.append((entry, pub))
    if policy.sole and accepted:
        incumbent = [pair for pair in accepted if str(pair[1].get("gid", "")) in connected]
        owner = (incumbent[0] if incumbent else min(accepted, key=_publisher_age_key))[0]
        for entry, pub in [pair for pair in accepted if pair[0] is not owner]:
            refused.append((entry, pub, f"node {owner.get('fqn')} (pid {owner.get('pid')}) publishes it already "
                                        "and is its only publisher taken"))
        accepted = [pair for pair in accepted if pair[0] is owner]
    return accepted, refused
