#!/usr/bin/python3
"""A client of pneu-dash's Foxglove WebSocket endpoint (python3-websocket, python3-jsonschema): takes
serverInfo and advertise, subscribes to every channel, and holds each message to the JSON Schema its
channel advertised (draft 2020-12). Fails when a required topic brings fewer messages than asked,
when a message does not follow its schema, or an error status comes.

usage: dash_client.py URL SECONDS TOPIC:MIN [TOPIC:MIN ...] [--time]
  --time  the server must have the capability "time" and send time messages (a log played)
"""
import json
import struct
import sys
import time

import jsonschema
import websocket


def main(argv):
    want_time = "--time" in argv
    args = [a for a in argv if a != "--time"]
    url, seconds = args[0], float(args[1])
    minimum = {w.split(":")[0]: int(w.split(":")[1]) for w in args[2:]}
    failures = []

    def fail(text):
        if len(failures) < 20:
            print("FAIL: " + text)
        failures.append(text)

    ws = websocket.create_connection(url, subprotocols=["foxglove.websocket.v1"], timeout=5)
    info = json.loads(ws.recv())
    if info.get("op") != "serverInfo":
        fail("the first message is not serverInfo: %r" % info)
    if "json" not in info.get("supportedEncodings", []):
        fail("serverInfo: no json encoding")
    if want_time and "time" not in info.get("capabilities", []):
        fail("serverInfo: no capability time")
    subs = {}
    counts, gaps, last = {}, {}, {}
    times = 0
    deadline = time.monotonic() + seconds
    next_sub = 0
    while time.monotonic() < deadline and not failures:
        if minimum and all(counts.get(t, 0) >= m for t, m in minimum.items()) and (times > 0 or not want_time):
            break
        try:
            opcode, data = ws.recv_data()
        except websocket.WebSocketTimeoutException:
            continue
        if opcode == websocket.ABNF.OPCODE_TEXT:
            msg = json.loads(data)
            if msg.get("op") == "advertise":
                for ch in msg["channels"]:
                    if ch["encoding"] != "json" or ch.get("schemaEncoding") != "jsonschema":
                        fail("%s: encoding %s, schemaEncoding %s" % (ch["topic"], ch["encoding"], ch.get("schemaEncoding")))
                    schema = json.loads(ch["schema"])
                    jsonschema.Draft202012Validator.check_schema(schema)
                    subs[next_sub] = (ch, jsonschema.Draft202012Validator(schema))
                    counts[ch["topic"]] = 0
                    gaps[ch["topic"]] = 0
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": next_sub, "channelId": ch["id"]}]}))
                    next_sub += 1
            elif msg.get("op") == "status":
                print("status (level %d): %s" % (msg["level"], msg["message"]))
                if msg["level"] == 2:
                    fail("an error status: " + msg["message"])
            continue
        if data[0] == 2:
            times += 1
            continue
        if data[0] != 1 or len(data) < 13:
            fail("a binary frame of op %d" % data[0])
            continue
        sub, = struct.unpack_from("<I", data, 1)
        if sub not in subs:
            fail("a message of unknown subscription %d" % sub)
            continue
        ch, validator = subs[sub]
        record = json.loads(data[13:].decode())
        errors = list(validator.iter_errors(record))
        if errors:
            fail("%s: %s in %s" % (ch["topic"], errors[0].message, json.dumps(record)[:300]))
            continue
        counts[ch["topic"]] += 1
        field = ch.get("sequenceField")
        if field:
            if ch["topic"] in last and record[field] > last[ch["topic"]] + 1:
                gaps[ch["topic"]] += record[field] - last[ch["topic"]] - 1
            last[ch["topic"]] = record[field]
    ws.close()
    for topic, m in minimum.items():
        if counts.get(topic, 0) < m:
            fail("%s: %d messages, fewer than %d" % (topic, counts.get(topic, 0), m))
    if want_time and times == 0:
        fail("no time message")
    for topic, n in sorted(counts.items()):
        print("%s: %d messages valid%s" % (topic, n, ", %d missing by its sequence" % gaps[topic] if gaps[topic] else ""))
    if want_time:
        print("time messages: %d" % times)
    if failures:
        print("FAIL: %d failure(s)" % len(failures))
        return 1
    print("PASSED")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
