#!/usr/bin/env python3
"""Stream a G-code program to a grbl-family controller by character counting.

An independent third-party client for testing whirl-sim: it shares no code with whirl's
own streamer (src/protocol/) and follows grbl's published character-counting method, as
described on the grbl wiki ("Interfacing with Grbl", streaming protocol: character
counting) and implemented by grbl's doc/script/stream.py (gnea/grbl):

- each line is stripped of comments and whitespace and upper-cased, as stream.py does
  (it removes whitespace and "( ... )" comments; "; ..." comments are removed here too,
  and lines left empty are not sent, so every line sent carries a block);
- the byte lengths of lines sent but not yet answered are kept in a list (newline
  included); the next line is sent only while sum(lengths) + len(next line) is less than
  the controller's RX buffer size, so the lines in flight fit in the N - 1 bytes a ring
  buffer of N bytes holds (stream.py waits one byte earlier: it tests the sum against
  RX_BUFFER_SIZE - 1);
- each "ok" or "error:N" answers the oldest line in flight and pops its length; anything
  else (status reports "<...>", "[MSG:...]" and other bracketed messages, ALARM lines,
  banners, blank lines) is shown on stderr and otherwise ignored.

No banner is required: a controller that booted before the port was opened sends none
after the client opens it (the banner of its power-up, if it waits in the port, as
whirl-sim leaves it on a pseudo-terminal, is old), so the client flushes its input and
starts. Every wait for an answer is bounded (--timeout, 10 s by default).

At the end one machine-readable line goes to stdout:

    lines=N ok=N error=N extra=N bytes=N elapsed_us=N

`extra` counts answers that arrived with no line in flight, during the stream or in a
short quiet period after the last answer. `bytes` counts the bytes written and
`elapsed_us` the microseconds from the first byte written to the last line's answer read
(0 if none was answered), so bytes x 10 / baud over it is how busy the client kept an
8N1 link. The exit status is 0 only when every line got exactly one "ok"; otherwise 1,
with the first line that got an error (its number in the program file and its text) or
the reason the stream stopped on stderr.

Requires Python 3 and pyserial.
"""

import argparse
import re
import sys
import time
from collections import deque

import serial

# stream.py's cleaning, re.sub('\s|\(.*?\)', '', line), plus ';' comments to the end of the
# line. One left-to-right pass, so a ';' inside "( ... )" stays part of that comment.
STRIP = re.compile(r"\s|\(.*?\)|;.*$")


# Seconds one read of the port may block. Longer waits loop over short reads, because
# changing pyserial's timeout reconfigures the port (tcsetattr) every time.
READ_POLL = 0.05


class StreamFailure(Exception):
    """The stream cannot go on (no answer in time, a line that can never fit)."""


def clean(line):
    """The block grbl is sent for one program line: no comments, no whitespace, upper case."""
    return STRIP.sub("", line).upper()


def is_answer(text):
    """Whether a controller line answers a sent line (only these consume a length)."""
    return text == "ok" or text.startswith("error:")


class Streamer:
    """grbl's character-counting stream over one open port, with its tallies."""

    def __init__(self, port, rx, timeout):
        self.port = port
        self.rx = rx
        self.timeout = timeout
        self.received = b""  # bytes read but not yet a complete line
        self.in_flight = deque()  # (program line number, block, bytes) awaiting an answer
        self.tally = {"lines": 0, "ok": 0, "error": 0, "extra": 0, "bytes": 0}
        self.first_error = None  # (program line number, block, answer)
        self.first_write = None  # time.monotonic() of the first byte written
        self.last_answer = None  # time.monotonic() of the last answer to a line in flight

    def elapsed_us(self):
        """Microseconds from the first byte written to the last answer, 0 without both."""
        if self.first_write is None or self.last_answer is None:
            return 0
        return round((self.last_answer - self.first_write) * 1e6)

    def read_line(self, wait):
        """The next complete line from the controller, stripped, or None after `wait` s."""
        deadline = time.monotonic() + wait
        while b"\n" not in self.received:
            if time.monotonic() >= deadline:
                return None
            # The port's own read timeout is short (READ_POLL), so this returns soon.
            self.received += self.port.read(max(1, self.port.in_waiting))
        line, self.received = self.received.split(b"\n", 1)
        return line.decode("ascii", errors="replace").strip()

    def take(self, text):
        """Account for one line from the controller: an answer pops the oldest length."""
        if not is_answer(text):
            if text:
                print(f"    MSG: {text!r}", file=sys.stderr)
            return
        if not self.in_flight:
            self.tally["extra"] += 1
            print(f"unexpected {text!r} with no line in flight", file=sys.stderr)
            return
        number, block, _ = self.in_flight.popleft()
        self.last_answer = time.monotonic()
        if text == "ok":
            self.tally["ok"] += 1
        else:
            self.tally["error"] += 1
            if self.first_error is None:
                self.first_error = (number, block, text)

    def take_waiting(self):
        """Take the answers that have already arrived, without waiting for more."""
        while self.port.in_waiting or b"\n" in self.received:
            text = self.read_line(READ_POLL)
            if text is None:
                return
            self.take(text)

    def wait_for_answer(self):
        """Block until the oldest line in flight is answered (other lines are taken too)."""
        before = len(self.in_flight)
        while len(self.in_flight) == before:
            text = self.read_line(self.timeout)
            if text is None:
                number, block, _ = self.in_flight[0]
                raise StreamFailure(
                    f"no answer within {self.timeout:g} s; waiting on line {number} {block!r}"
                )
            self.take(text)

    def send(self, number, block):
        """Send one block once it fits in what the controller's RX buffer has left."""
        data = (block + "\n").encode("ascii")
        if len(data) >= self.rx:
            raise StreamFailure(
                f"line {number} is {len(data)} bytes with its newline; "
                f"an RX buffer of {self.rx} holds {self.rx - 1}"
            )
        self.take_waiting()
        while sum(n for _, _, n in self.in_flight) + len(data) >= self.rx:
            self.wait_for_answer()
        if self.first_write is None:
            self.first_write = time.monotonic()
        self.port.write(data)
        self.in_flight.append((number, block, len(data)))
        self.tally["lines"] += 1
        self.tally["bytes"] += len(data)

    def run(self, program):
        """Stream `program` (its raw lines), then wait for every answer and any extra one."""
        for number, raw in enumerate(program, start=1):
            block = clean(raw)
            if not block:
                continue
            if not block.isascii():
                raise StreamFailure(f"line {number} {block!r} is not ASCII")
            self.send(number, block)
        while self.in_flight:
            self.wait_for_answer()
        # A second answer to some line would come now: listen until the link is quiet.
        while (text := self.read_line(0.5)) is not None:
            self.take(text)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("port", help="serial device (or pseudo-terminal) of the controller")
    parser.add_argument("program", help="G-code file to stream")
    parser.add_argument(
        "--rx",
        type=int,
        default=1024,
        help="controller RX buffer size in bytes (grblHAL 1024, grbl 128)",
    )
    parser.add_argument("--baud", type=int, default=115200, help="link rate, bits per second")
    parser.add_argument(
        "--timeout",
        type=float,
        default=10.0,
        help="seconds to wait for an answer before giving up",
    )
    args = parser.parse_args()
    if args.rx < 2:
        parser.error("--rx must be at least 2 (a ring buffer of N bytes holds N - 1)")
    if args.timeout <= 0:
        parser.error("--timeout must be positive")

    try:
        with open(args.program, encoding="utf-8", errors="replace") as f:
            program = f.read().splitlines()
    except OSError as e:
        print(f"failed: cannot read the program: {e}", file=sys.stderr)
        return 1

    streamer = None
    failure = None
    try:
        with serial.Serial(args.port, args.baud, timeout=READ_POLL) as port:
            # No banner is awaited: the controller may have booted long before the port
            # was opened, and then it sends none.
            port.reset_input_buffer()
            streamer = Streamer(port, args.rx, args.timeout)
            streamer.run(program)
    except (StreamFailure, serial.SerialException) as e:
        failure = str(e)

    ok = failure is None
    if streamer is not None:
        tally = dict(streamer.tally, elapsed_us=streamer.elapsed_us())
        print(" ".join(f"{k}={v}" for k, v in tally.items()))
        if streamer.first_error is not None:
            number, block, text = streamer.first_error
            print(f"first error: line {number} {block!r} answered {text}", file=sys.stderr)
            ok = False
        if streamer.tally["extra"]:
            print(f"{streamer.tally['extra']} answers came with no line in flight", file=sys.stderr)
            ok = False
    if failure is not None:
        print(f"failed: {failure}", file=sys.stderr)
    # With no failure every line sent was answered, so no error and no extra answer means
    # that every line got exactly one "ok".
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
