"""A long randomized session driven through the fastmcp client, as an LLM agent would.

Usage: python mcp_long_session.py URL CALLS SEED

Seeded tool calls drawn from what an LLM does (detect, pick and place, relative places, pushes,
move2by, invalid arguments, recoveries). After every failure it runs the documented recovery:
clear_collision_detected after a collision, get_detected_objects, and place_object where the
reply suggested when an object is still held. A recovery that does not bring the robot back is
counted as stuck. Prints one JSON object: calls, successes, failures by kind, collisions, stuck
states, what the replies say is held, and the last detection. The Rust test
(tests/mcp_python_long_session.rs) checks it against the simulator's ground truth.
"""

import asyncio
import json
import random
import re
import sys
import warnings

warnings.filterwarnings("ignore")

from fastmcp import Client  # noqa: E402
from fastmcp.client.transports import SSETransport  # noqa: E402

LOCATIONS = ["left next to", "right next to", "above", "below", "on top of", "inside"]
DIRECTIONS = ["up", "down", "left", "right"]
STILL_HELD = re.compile(r"; '([^']+)' is still held: put it down with place_object(?:, e\.g\. at \[([-\d.]+), ([-\d.]+)\])?")


def text_of(result):
    return "\n".join(c.text for c in result.content if getattr(c, "type", "") == "text")


def kind_of(text):
    if text.startswith("❌ Validation Error"):
        return "invalid arguments"
    for needle, kind in [
        ("collision detected", "collision"),
        ("would not fit", "placement refused"),
        ("would cover the marker", "placement refused"),
        ("fingers would hit", "placement refused"),
        ("no room", "placement refused"),
        ("would stick out", "placement refused"),
        ("would shove", "placement refused"),
        ("would overhang", "placement refused"),
        ("within 5 cm", "object not found"),
        ("holds nothing", "nothing held"),
        ("already holds", "gripper busy"),
        ("mm wide across the grasp", "too wide"),
        ("outside workspace", "outside workspace"),
        ("unknown workspace", "unknown workspace"),
    ]:
        if needle in text:
            return kind
    return "other"


class Session:
    def __init__(self, client, seed):
        self.client = client
        self.rng = random.Random(seed)
        self.report = {"calls": 0, "succeeded": 0, "failures": {}, "collisions": 0, "stuck": []}
        self.seen = []
        self.holding = None
        self.put_down_at = None

    async def call(self, tool, args):
        self.report["calls"] += 1
        result = await self.client.call_tool(tool, args, raise_on_error=False)
        text = text_of(result)
        if text.startswith("✓"):
            self.report["succeeded"] += 1
            if tool == "pick_object":
                self.holding = args["object_name"]
            elif tool in ("place_object", "pick_place_object", "move2by"):
                self.holding = None
            if tool == "get_detected_objects":
                data = (result.structured_content or {}).get("data") or []
                self.seen = [
                    (o["label"], [o["position"]["center_of_mass"]["x"], o["position"]["center_of_mass"]["y"]])
                    for o in data
                ]
        else:
            kind = kind_of(text)
            self.report["failures"][kind] = self.report["failures"].get(kind, 0) + 1
            if kind == "collision":
                self.report["collisions"] += 1
            held = STILL_HELD.search(text)
            if held:
                self.holding = held.group(1)
                self.put_down_at = [float(held.group(2)), float(held.group(3))] if held.group(2) else None
        return text

    def point(self):
        return [round(self.rng.uniform(0.185, 0.315), 3), round(self.rng.uniform(-0.065, 0.065), 3)]

    def next_call(self):
        roll = self.rng.randrange(100)
        if roll < 15 or not self.seen:
            return "get_detected_objects", {}
        label, at = self.rng.choice(self.seen)
        if roll < 40:
            args = {"object_name": label, "pick_coordinate": at}
            if self.rng.random() < 0.5:
                args["place_coordinate"] = self.point()
            else:
                args["place_coordinate"] = self.rng.choice(self.seen)[1]
                args["location"] = self.rng.choice(LOCATIONS)
            return "pick_place_object", args
        if roll < 48:
            return "pick_object", {"object_name": label, "pick_coordinate": at}
        if roll < 58:
            if self.rng.random() < 0.5:
                return "place_object", {"place_coordinate": self.point()}
            return "place_object", {
                "place_coordinate": self.rng.choice(self.seen)[1],
                "location": self.rng.choice(LOCATIONS + ["close to"]),
            }
        if roll < 70:
            return "push_object", {
                "object_name": label,
                "push_coordinate": at,
                "direction": self.rng.choice(DIRECTIONS),
                "distance": float(self.rng.randint(10, 40)),
            }
        if roll < 78:
            return "move2by", {
                "object_name": label,
                "pick_coordinate": at,
                "direction": self.rng.choice(DIRECTIONS),
                "distance": self.rng.randint(1, 5) / 100.0,
            }
        if roll < 90:
            return self.rng.choice(
                [
                    ("pick_object", {"object_name": "", "pick_coordinate": at}),
                    ("pick_place_object", {"object_name": label, "pick_coordinate": [at[0]], "place_coordinate": [0.25, 0.0]}),
                    ("pick_place_object", {"object_name": label, "pick_coordinate": at, "place_coordinate": [0.25, 0.0], "z_offset": 0.5}),
                    ("push_object", {"object_name": label, "push_coordinate": at, "direction": "sideways", "distance": 20.0}),
                    ("place_object", {"place_coordinate": [0.25, 0.0], "location": "sideways"}),
                    ("pick_object", {"object_name": "unicorn", "pick_coordinate": at}),
                    ("move2observation_pose", {"workspace_id": "nope_ws"}),
                ]
            )
        if roll < 95:
            tool = self.rng.choice(["clear_collision_detected", "move2observation_pose", "calibrate"])
            return tool, ({"workspace_id": "niryo_ws"} if tool == "move2observation_pose" else {})
        return self.rng.choice(["get_largest_free_space_with_center", "get_object_labels_as_string", "get_system_status"]), {}

    async def recover(self, text):
        if "collision detected" in text:
            cleared = await self.call("clear_collision_detected", {})
            if not cleared.startswith("✓"):
                self.report["stuck"].append(f"clear failed: {cleared}")
        seen = await self.call("get_detected_objects", {})
        if not seen.startswith("✓"):
            self.report["stuck"].append(f"detection after a failure: {seen}")
            return
        if self.holding is not None:
            spots = [self.put_down_at] if self.put_down_at else []
            free = await self.client.call_tool("get_largest_free_space_with_center", {}, raise_on_error=False)
            centre = ((free.structured_content or {}).get("data") or {}).get("center")
            if centre:
                spots.append(centre)
            last = ""
            for spot in spots:
                last = await self.call("place_object", {"place_coordinate": spot})
                if last.startswith("✓"):
                    self.holding = None
                    return
            self.report["stuck"].append(f"'{self.holding}' could not be put down: {last}")

    async def run(self, calls):
        while self.report["calls"] < calls:
            tool, args = self.next_call()
            text = await self.call(tool, args)
            if not text.startswith("✓") and not text.startswith("❌ Validation Error"):
                await self.recover(text)
        # A last look, so that the report's detection is the world as it is now.
        await self.call("get_detected_objects", {})
        self.report["holding"] = self.holding
        self.report["seen"] = [{"label": label, "at": at} for label, at in self.seen]
        return self.report


async def main(url, calls, seed):
    async with Client(SSETransport(url)) as client:
        report = await Session(client, seed).run(calls)
    print(json.dumps(report))


if __name__ == "__main__":
    asyncio.run(main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3])))
