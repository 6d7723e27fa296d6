"""stickslip.cluster.Connecting: a LocalCluster started in a thread while the fit reads its
data, handed over, or closed when the caller or the preparation fails."""

from __future__ import annotations

import pytest

from stickslip.cluster import Connecting


def test_the_cluster_started_aside_is_handed_over_prepared_and_closed_by_its_owner():
    seen = []

    def prepare(client):
        seen.append(client.submit(sum, [1, 2, 3]).result())

    connecting = Connecting(None, 1, prepare)
    client, cluster = connecting.result()
    try:
        assert seen == [6]  # prepared in the thread, before result() returned
        assert client.submit(lambda: 41 + 1).result() == 42
        assert len(cluster.workers) == 1
    finally:
        connecting.close()
    assert client.status == "closed"
    assert cluster.status.name == "closed"


def test_a_preparation_that_fails_raises_in_the_caller_and_leaves_no_cluster():
    made = []

    def prepare(client):
        made.append(client)
        raise ValueError("the FMU cannot be sent")

    connecting = Connecting(None, 1, prepare)
    with pytest.raises(ValueError, match="cannot be sent"):
        connecting.result()
    (client,) = made
    assert client.status == "closed"
    assert client.cluster.status.name == "closed"
