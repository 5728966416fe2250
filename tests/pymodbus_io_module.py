#!/usr/bin/python3
"""An analog I/O module with the register map of config/hil.yaml, served by pymodbus 3.0.

A Modbus TCP implementation not written in this project, for interoperability tests of pneud's
modbus backend (tests/test_pymodbus_interop.cpp). It serves constant sensor voltages and records
the valve voltages it receives:

  holding 0, 1, 2    position, p_P, p_N: unsigned, 0..65535 for 0..10 V
  holding 16, 17     valve_p, valve_n: signed, -32767..32767 for -10..10 V

Sensor calibration (hil.yaml): position 20 V/m with 5 V at mid-stroke, pressures 1e-5 V/Pa.

On SIGTERM/SIGINT, or after --duration seconds, it prints to stdout

  sensors: y = ... m (word W), p_P = ... Pa (word W), p_N = ... Pa (word W)
  requests: fc3 N, fc4 N, fc6 N, fc16 N, fc23 N
  valve writes: N
  valve history: (u_P, u_N) V x count, ... (the runs of equal values, oldest first, at most 8)
  last valve voltages: u_P = +x.xxxxxx V, u_N = +x.xxxxxx V (words a, b)

and exits 0. Loopback only. Run with /usr/bin/python3 (Debian's python3-pymodbus). With --check it
only imports what it needs and exits 0; a module that cannot be imported exits 3 at once, naming the
Debian package to install (stderr).
"""

import argparse
import asyncio
import logging
import signal
import sys

# The Debian package of each third-party module this imports, directly or through pymodbus 3.0's
# server (which needs serial_asyncio, only a Recommends of python3-pymodbus).
DEBIAN_PACKAGES = {"pymodbus": "python3-pymodbus", "serial_asyncio": "python3-serial-asyncio",
                   "serial": "python3-serial"}
EXIT_MISSING_MODULE = 3

try:
    from pymodbus.datastore import (ModbusSequentialDataBlock, ModbusServerContext,
                                    ModbusSlaveContext)
    from pymodbus.server import StartAsyncTcpServer
except ImportError as error:
    missing = (getattr(error, "name", None) or "?").split(".")[0]
    print(f"pymodbus_io_module: cannot import {missing}: install the Debian package "
          f"{DEBIAN_PACKAGES.get(missing, 'that provides it')} (scripts/deps installs it) [{error}]",
          file=sys.stderr, flush=True)
    sys.exit(EXIT_MISSING_MODULE)

# The register map of config/hil.yaml.
REG_POSITION, REG_PRESSURE_P, REG_PRESSURE_N = 0, 1, 2
REG_VALVE_P, REG_VALVE_N = 16, 17
SENSOR_FULL_SCALE_V, SENSOR_RAW_MAX = 10.0, 65535
VALVE_FULL_SCALE_V, VALVE_RAW_MAX = 10.0, 32767

# The sensor calibration of config/hil.yaml.
POSITION_GAIN_V_PER_M, POSITION_OFFSET_V = 20.0, 5.0
PRESSURE_GAIN_V_PER_PA = 1.0e-5

# What the module serves: the carriage at 0.100 m (7.0 V), p_P = 3 bar (3.0 V), p_N = 4 bar (4.0 V).
POSITION_M, PRESSURE_P_PA, PRESSURE_N_PA = 0.100, 3.0e5, 4.0e5

HISTORY_RUNS = 8


def sensor_word(volts):
    """Volts -> unsigned 16-bit word, 0..65535 for 0..10 V."""
    return max(0, min(SENSOR_RAW_MAX, round(volts / SENSOR_FULL_SCALE_V * SENSOR_RAW_MAX)))


def sensor_volts(word):
    return word * SENSOR_FULL_SCALE_V / SENSOR_RAW_MAX


def valve_volts(word):
    """Signed 16-bit word (two's complement), -32767..32767 for -10..10 V -> volts."""
    raw = word - 0x10000 if word & 0x8000 else word
    return raw * VALVE_FULL_SCALE_V / VALVE_RAW_MAX


class ValveRecorder:
    """What the master wrote to the valve registers, as runs of equal (valve_p, valve_n) words."""

    def __init__(self):
        self.words = [0, 0]
        self.writes = 0
        self.runs = []  # [[word_p, word_n, count], ...]

    def record(self, address, values):
        touched = False
        for offset, value in enumerate(values):
            reg = address + offset
            if reg in (REG_VALVE_P, REG_VALVE_N):
                self.words[reg - REG_VALVE_P] = value
                touched = True
        if not touched:
            return
        self.writes += 1
        if self.runs and self.runs[-1][:2] == self.words:
            self.runs[-1][2] += 1
        else:
            self.runs.append([self.words[0], self.words[1], 1])
            del self.runs[:-HISTORY_RUNS]


class RecordingBlock(ModbusSequentialDataBlock):
    """Holding registers that report writes to the recorder."""

    def __init__(self, address, values, recorder):
        super().__init__(address, values)
        self.recorder = recorder

    def setValues(self, address, values):  # noqa: N802 (pymodbus' name)
        super().setValues(address, values)
        self.recorder.record(address, values if isinstance(values, list) else [values])


class CountingSlaveContext(ModbusSlaveContext):
    """Counts the requests by function code: reads (FC3, FC4, FC23) by their one getValues(), writes
    (FC6, FC16) by their one setValues() (FC6 reads its register back to echo it)."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.requests = {}

    def getValues(self, fc_as_hex, address, count=1):  # noqa: N802
        if fc_as_hex in (3, 4, 23):
            self.requests[fc_as_hex] = self.requests.get(fc_as_hex, 0) + 1
        return super().getValues(fc_as_hex, address, count)

    def setValues(self, fc_as_hex, address, values):  # noqa: N802
        if fc_as_hex in (6, 16):
            self.requests[fc_as_hex] = self.requests.get(fc_as_hex, 0) + 1
        super().setValues(fc_as_hex, address, values)


def build_context(unit, recorder):
    words = [0] * 32
    words[REG_POSITION] = sensor_word(POSITION_GAIN_V_PER_M * POSITION_M + POSITION_OFFSET_V)
    words[REG_PRESSURE_P] = sensor_word(PRESSURE_GAIN_V_PER_PA * PRESSURE_P_PA)
    words[REG_PRESSURE_N] = sensor_word(PRESSURE_GAIN_V_PER_PA * PRESSURE_N_PA)
    # zero_mode: the block's addresses are the wire's (no +1 shift).
    slave = CountingSlaveContext(hr=RecordingBlock(0, words, recorder), ir=ModbusSequentialDataBlock(0, list(words)),
                                 zero_mode=True)
    return ModbusServerContext(slaves={unit: slave}, single=False), slave, words


def report(slave, words, recorder, out):
    y = (sensor_volts(words[REG_POSITION]) - POSITION_OFFSET_V) / POSITION_GAIN_V_PER_M
    p_p = sensor_volts(words[REG_PRESSURE_P]) / PRESSURE_GAIN_V_PER_PA
    p_n = sensor_volts(words[REG_PRESSURE_N]) / PRESSURE_GAIN_V_PER_PA
    print(f"sensors: y = {y:.9f} m (word {words[REG_POSITION]}), p_P = {p_p:.3f} Pa (word {words[REG_PRESSURE_P]}), "
          f"p_N = {p_n:.3f} Pa (word {words[REG_PRESSURE_N]})", file=out)
    print("requests: " + ", ".join(f"fc{fc} {slave.requests.get(fc, 0)}" for fc in (3, 4, 6, 16, 23)), file=out)
    print(f"valve writes: {recorder.writes}", file=out)
    print("valve history: " + ", ".join(f"({valve_volts(p):+.6f}, {valve_volts(n):+.6f}) V x {c}"
                                        for p, n, c in recorder.runs), file=out)
    p, n = recorder.words
    print(f"last valve voltages: u_P = {valve_volts(p):+.6f} V, u_N = {valve_volts(n):+.6f} V (words {p}, {n})",
          file=out)
    out.flush()


async def serve(args):
    recorder = ValveRecorder()
    context, slave, words = build_context(args.unit, recorder)
    # ignore_missing_slaves: a request to another unit goes unanswered, as on a real gateway-less module.
    server = await StartAsyncTcpServer(context=context, address=("127.0.0.1", args.port), defer_start=True,
                                       allow_reuse_address=True, ignore_missing_slaves=True)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, stop.set)
    task = asyncio.create_task(server.serve_forever())
    await server.serving
    print(f"pymodbus_io_module: listening on 127.0.0.1:{args.port}, unit {args.unit}", file=sys.stderr, flush=True)
    try:
        await asyncio.wait_for(stop.wait(), timeout=args.duration if args.duration > 0 else None)
    except asyncio.TimeoutError:
        pass
    await server.shutdown()
    task.cancel()
    try:
        await task
    except asyncio.CancelledError:
        pass
    report(slave, words, recorder, sys.stdout)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--check", action="store_true", help="only check that the imports succeed, exit 0")
    parser.add_argument("--port", type=int, help="TCP port on 127.0.0.1")
    parser.add_argument("--unit", type=int, default=1, help="unit (slave) identifier, default 1")
    parser.add_argument("--duration", type=float, default=0.0, help="stop after this many seconds (0: on a signal)")
    args = parser.parse_args()
    if args.check:
        return 0
    if args.port is None:
        parser.error("--port is required")
    # pymodbus 3.0 configures the root logger at import and logs every closed session as an error.
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    asyncio.run(serve(args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
