"""Drives `robotd fake-widowx`'s servo bus with ROBOTIS's own SDK (dynamixel-sdk 4.1.0).

Usage: dynamixel_sdk_session.py DEVICE

Pings every servo, reads and writes the control-table items robotd uses (models, operating and
drive mode, secondary ID, torque, profile, goal and present position, hardware error status),
sync-reads and sync-writes positions, moves a joint, and prints one JSON object of what it saw.
"""

import json
import sys
import time

from dynamixel_sdk import (
    COMM_SUCCESS,
    GroupSyncRead,
    GroupSyncWrite,
    PacketHandler,
    PortHandler,
)

device = sys.argv[1]
port = PortHandler(device)
packets = PacketHandler(2.0)
if not port.openPort() or not port.setBaudRate(1000000):
    raise SystemExit(f"cannot open {device}")

seen = {}


def check(what, result, error):
    if result != COMM_SUCCESS:
        raise SystemExit(f"{what}: {packets.getTxRxResult(result)}")
    return error


# Every servo answers its ping with its model.
models = {}
for servo in range(1, 10):
    model, result, error = packets.ping(port, servo)
    check(f"ping {servo}", result, error)
    models[servo] = model
seen["models"] = models
# An ID that is not on the bus does not answer.
_, result, _ = packets.ping(port, 42)
seen["ping_42"] = packets.getTxRxResult(result)

# Factory settings robotd reads before writing.
mode, result, error = packets.read1ByteTxRx(port, 9, 11)
check("read operating mode", result, error)
seen["gripper_mode"] = mode
secondary, result, error = packets.read1ByteTxRx(port, 3, 12)
check("read secondary id", result, error)
seen["shadow_secondary_id"] = secondary

# EEPROM is writable with torque off only.
result, error = packets.write1ByteTxRx(port, 1, 64, 1)
check("torque on", result, error)
result, error = packets.write1ByteTxRx(port, 1, 11, 16)
seen["eeprom_with_torque_on"] = packets.getRxPacketError(error)
result, error = packets.write1ByteTxRx(port, 1, 64, 0)
check("torque off", result, error)
result, error = packets.write1ByteTxRx(port, 1, 11, 3)
seen["eeprom_with_torque_off"] = check("write operating mode", result, error)

# A goal outside the position limits is refused.
result, error = packets.write1ByteTxRx(port, 1, 64, 1)
check("torque on", result, error)
result, error = packets.write4ByteTxRx(port, 1, 116, 5000)
seen["goal_out_of_limits"] = packets.getRxPacketError(error)

# Profile, then a goal on the waist: it moves the simulated arm.
result, error = packets.write4ByteTxRx(port, 1, 112, 0)
check("profile velocity", result, error)
start, result, error = packets.read4ByteTxRx(port, 1, 132)
check("present position", result, error)
seen["waist_start"] = start
result, error = packets.write4ByteTxRx(port, 1, 116, start + 200)
check("goal position", result, error)
deadline = time.time() + 2.0
position = start
while time.time() < deadline:
    position, result, error = packets.read4ByteTxRx(port, 1, 132)
    check("present position", result, error)
    if abs(position - (start + 200)) <= 1:
        break
    time.sleep(0.01)
seen["waist_after_goal"] = position

# Sync write of two goals and a sync read of all nine positions.
for servo in (6, 8):
    packets.write1ByteTxRx(port, servo, 64, 1)
writer = GroupSyncWrite(port, packets, 116, 4)
for servo, goal in ((6, 2148), (8, 1948)):
    writer.addParam(servo, list(goal.to_bytes(4, "little")))
check("sync write", writer.txPacket(), 0)
time.sleep(0.2)
reader = GroupSyncRead(port, packets, 132, 4)
for servo in range(1, 10):
    reader.addParam(servo)
check("sync read", reader.txRxPacket(), 0)
seen["sync_read"] = {
    servo: reader.getData(servo, 132, 4) for servo in range(1, 10) if reader.isAvailable(servo, 132, 4)
}

status, result, error = packets.read1ByteTxRx(port, 4, 70)
check("hardware error status", result, error)
seen["hardware_error_status"] = status
result, error = packets.reboot(port, 4)
seen["reboot"] = packets.getTxRxResult(result)

port.closePort()
print(json.dumps(seen))
