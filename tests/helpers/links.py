"""The companion's real link fed frames by hand, as its socket would hand them over."""

from __future__ import annotations

import asyncio

from companion.link.pymavlink_link import PymavlinkLink


class _Sink:
    """Where the link's own sends go while no socket is open: nowhere."""

    def sendto(self, data: bytes, peer: object) -> None:
        pass

    def close(self) -> None:
        pass


def fed_link(frames: list[bytes], peer: tuple[str, int], **options: object) -> PymavlinkLink:
    """A ``PymavlinkLink(**options)`` whose receive path got ``frames`` from ``peer``, after its reader
    ran five event-loop turns (enough to read them) and stopped."""

    async def main() -> PymavlinkLink:
        link = PymavlinkLink("udpin://127.0.0.1:0", **options)  # type: ignore[arg-type]
        link._transport = _Sink()  # type: ignore[assignment]
        for f in frames:
            link._received(f, peer)
        stop = asyncio.Event()
        reader = asyncio.create_task(link.run(stop))
        for _ in range(5):
            await asyncio.sleep(0)
        stop.set()
        await reader
        return link

    return asyncio.run(main())
