"""Telemetry fan-out: every subscriber gets each item through its own loop; a slow one loses its oldest items."""

from __future__ import annotations

import asyncio
import threading

from backend.devices.fanout import TelemetryFanout


def test_items_from_another_thread_reach_every_subscriber_in_order():
    async def main() -> tuple[list, list]:
        fan = TelemetryFanout()
        loop = asyncio.get_running_loop()
        a, b = asyncio.Queue(), asyncio.Queue()
        fan.subscribe(a, loop)
        fan.subscribe(b, loop)
        assert fan
        sender = threading.Thread(target=lambda: [fan.publish({"seq": i}) for i in range(5)])
        sender.start()
        got_a = [(await asyncio.wait_for(a.get(), 5))["seq"] for _ in range(5)]
        got_b = [(await asyncio.wait_for(b.get(), 5))["seq"] for _ in range(5)]
        sender.join()
        fan.unsubscribe(a)
        fan.unsubscribe(b)
        assert not fan
        return got_a, got_b

    assert asyncio.run(main()) == ([0, 1, 2, 3, 4], [0, 1, 2, 3, 4])


def test_a_full_queue_drops_its_oldest_item_and_the_publisher_never_waits():
    async def main() -> list:
        fan = TelemetryFanout()
        q: asyncio.Queue = asyncio.Queue(maxsize=3)
        fan.subscribe(q, asyncio.get_running_loop())
        for i in range(10):
            fan.publish({"seq": i})
        await asyncio.sleep(0)          # let the loop run the offers scheduled above
        return [q.get_nowait()["seq"] for _ in range(q.qsize())]

    assert asyncio.run(main()) == [7, 8, 9]


def test_a_subscriber_whose_loop_closed_is_dropped():
    fan = TelemetryFanout()
    loop = asyncio.new_event_loop()
    loop.close()
    fan.subscribe(asyncio.Queue(), loop)
    fan.publish({"seq": 1})
    assert not fan
