"""A fastmcp client asking robotd's MCP edge for camera pictures (get_camera_image).

Usage: python mcp_camera_image.py URL OUT_DIR [ROUNDS]
(URL ending in /sse: legacy SSE; /mcp: streamable HTTP)

Calls get_camera_image once (which may move the arm to the observation pose) and writes the
JPEG it got to OUT_DIR/camera.jpg, then, with the arm at the pose, times ROUNDS calls of
get_camera_image interleaved with ROUNDS calls of get_detected_objects (the baseline: a call
answered from the same view, without a picture). Prints one JSON object with what it saw and
the timings in milliseconds. Used by tests/mcp_camera_image.rs for fastmcp 2.x and 4.x, and
for the BENCHMARKS.md figure.
"""

import asyncio
import base64
import json
import os
import statistics
import sys
import time
import warnings

warnings.filterwarnings("ignore")

import fastmcp  # noqa: E402
from fastmcp import Client  # noqa: E402
from fastmcp.client.transports import SSETransport, StreamableHttpTransport  # noqa: E402


def summary(values):
    values = sorted(values)
    if not values:
        return {}
    return {
        "p50": statistics.median(values),
        "p95": values[min(len(values) - 1, int(round(0.95 * (len(values) - 1))))],
        "min": values[0],
        "max": values[-1],
        "n": len(values),
    }


async def main(url, out_dir, rounds):
    transport = SSETransport(url) if url.rstrip("/").endswith("/sse") else StreamableHttpTransport(url)
    report = {"transport": type(transport).__name__, "fastmcp": fastmcp.__version__}
    async with Client(transport) as client:
        tools = await client.list_tools()
        report["tools"] = [t.name for t in tools]
        first = await client.call_tool("get_camera_image", {})
        report["content_types"] = [c.type for c in first.content]
        texts = [c.text for c in first.content if c.type == "text"]
        images = [c for c in first.content if c.type == "image"]
        report["text"] = texts[0] if texts else None
        report["data"] = first.data
        report["structured"] = first.structured_content
        if images:
            jpeg = base64.b64decode(images[0].data)
            report["mime_type"] = images[0].mimeType
            report["jpeg_bytes"] = len(jpeg)
            with open(os.path.join(out_dir, "camera.jpg"), "wb") as f:
                f.write(jpeg)
        plain = await client.call_tool("get_camera_image", {"annotated": False})
        plain_images = [c for c in plain.content if c.type == "image"]
        if plain_images:
            with open(os.path.join(out_dir, "plain.jpg"), "wb") as f:
                f.write(base64.b64decode(plain_images[0].data))
        invalid = await client.call_tool("get_camera_image", {"max_width": 5, "annotated": "yes"},
                                         raise_on_error=False)
        report["invalid_text"] = "\n".join(c.text for c in invalid.content if c.type == "text")
        picture_ms, baseline_ms, sizes = [], [], []
        for _ in range(rounds):
            started = time.perf_counter()
            result = await client.call_tool("get_camera_image", {})
            picture_ms.append((time.perf_counter() - started) * 1e3)
            sizes.extend(len(base64.b64decode(c.data)) for c in result.content if c.type == "image")
            started = time.perf_counter()
            await client.call_tool("get_detected_objects", {})
            baseline_ms.append((time.perf_counter() - started) * 1e3)
        report["picture_ms"] = summary(picture_ms)
        report["baseline_ms"] = summary(baseline_ms)
        report["max_jpeg_bytes"] = max(sizes) if sizes else None
    print(json.dumps(report))


if __name__ == "__main__":
    rounds = int(sys.argv[3]) if len(sys.argv) > 3 else 10
    asyncio.run(main(sys.argv[1], sys.argv[2], rounds))
