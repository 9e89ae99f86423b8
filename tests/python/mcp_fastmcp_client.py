"""A fastmcp client of robotd's MCP edge, as labs drive the Python robot-environment server.

Usage: python mcp_fastmcp_client.py URL   (URL ending in /sse: legacy SSE; /mcp: streamable HTTP)

Lists the tools, calls a detection tool, a workspace tool, a validation failure, and a pick and
place with a progress handler, and prints one JSON object with what it saw. The Rust test
(tests/mcp_python_clients.rs) runs it against a served robotd and checks the JSON.
"""

import asyncio
import json
import sys
import warnings

warnings.filterwarnings("ignore")

from fastmcp import Client  # noqa: E402
from fastmcp.client.transports import SSETransport, StreamableHttpTransport  # noqa: E402


# A free spot of the default scene for the pencil (120 × 12 mm along x).
PLACE = [0.27, -0.01]


def text_of(result):
    return "\n".join(c.text for c in result.content if getattr(c, "type", "") == "text")


async def main(url: str) -> None:
    transport = SSETransport(url) if url.rstrip("/").endswith("/sse") else StreamableHttpTransport(url)
    progress = []

    async def on_progress(done, total, message):
        progress.append({"progress": done, "total": total, "message": message})

    report = {"transport": type(transport).__name__}
    async with Client(transport) as client:
        tools = await client.list_tools()
        report["tools"] = [t.name for t in tools]
        report["output_schemas"] = sum(1 for t in tools if t.outputSchema)

        coordinate = await client.call_tool(
            "get_workspace_coordinate_from_point",
            {"workspace_id": "niryo_ws", "point": "lower right corner"},
        )
        report["coordinate_text"] = text_of(coordinate)
        report["coordinate_structured"] = coordinate.structured_content
        # What fastmcp users read: the reply text, as with the Python server.
        report["coordinate_data"] = coordinate.data

        objects = await client.call_tool("get_detected_objects", {"label": "pencil"})
        report["objects_text"] = text_of(objects)
        pencil = objects.structured_content["data"][0]
        com = pencil["position"]["center_of_mass"]

        invalid = await client.call_tool("pick_object", {"object_name": "", "pick_coordinate": [1]},
                                         raise_on_error=False)
        report["invalid_text"] = text_of(invalid)

        picked = await client.call_tool(
            "pick_place_object",
            {
                "object_name": "pencil",
                "pick_coordinate": [com["x"], com["y"]],
                "place_coordinate": PLACE,
            },
            progress_handler=on_progress,
        )
        report["pick_place_text"] = text_of(picked)
        report["pick_place_data"] = picked.data
        report["progress"] = progress

        moved = await client.call_tool("get_detected_objects", {"label": "pencil"})
        report["pencil_after"] = moved.structured_content["data"]
    print(json.dumps(report))


if __name__ == "__main__":
    asyncio.run(main(sys.argv[1]))
