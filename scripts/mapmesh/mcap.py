"""A writer of MCAP files (https://mcap.dev/spec, format version 0): JSON messages in
uncompressed chunks, each with its message indexes, and a summary section (schemas, channels,
statistics, chunk indexes and their offsets) so that indexed readers can seek. Every CRC is
written. Debian has no MCAP library and Python here has only the standard library, so this is
written from the specification; tests read its files back with the MCAP project's own reader
(npm @mcap/core), never with this module alone."""

import json
import os
import struct
import zlib

MAGIC = b"\x89MCAP0\r\n"
OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE = 0x01, 0x02, 0x03, 0x04, 0x05
OP_CHUNK, OP_MESSAGE_INDEX, OP_CHUNK_INDEX, OP_STATISTICS = 0x06, 0x07, 0x08, 0x0B
OP_SUMMARY_OFFSET, OP_DATA_END = 0x0E, 0x0F
CHUNK_BYTES = 1 << 20  # a chunk is closed past this many bytes of records


def _string(s):
    b = s.encode()
    return struct.pack("<I", len(b)) + b


def _map(pairs, pack):
    body = b"".join(pack(k, v) for k, v in pairs)
    return struct.pack("<I", len(body)) + body


def _record(op, body):
    return struct.pack("<BQ", op, len(body)) + body


class Writer:
    """Collects schemas, channels and messages; `finish(path)` writes the file with the messages in
    log-time order (ties in the order they were added)."""

    def __init__(self, profile="", library="mapmesh"):
        self.profile, self.library = profile, library
        self.schemas = []   # [(id, name, encoding, data)]
        self.channels = []  # [(id, schema id, topic, message encoding, metadata)]
        self.messages = []  # [(log time ns, order, channel id, data)]
        self._by_topic = {}
        self._schema_ids = {}

    def schema(self, name, json_schema):
        """The id of the JSON schema `name` (added on first use)."""
        if name not in self._schema_ids:
            self._schema_ids[name] = len(self.schemas) + 1
            self.schemas.append((self._schema_ids[name], name, "jsonschema",
                                 json.dumps(json_schema, sort_keys=True).encode()))
        return self._schema_ids[name]

    def channel(self, topic, schema_name, json_schema, metadata=None):
        """The id of the JSON channel on `topic` with the schema (added on first use)."""
        if topic not in self._by_topic:
            cid = len(self.channels) + 1
            self.channels.append((cid, self.schema(schema_name, json_schema), topic, "json",
                                  sorted((metadata or {}).items())))
            self._by_topic[topic] = cid
        return self._by_topic[topic]

    def message(self, channel_id, log_time_ns, value):
        self.messages.append((int(log_time_ns), len(self.messages), channel_id,
                              json.dumps(value, separators=(",", ":")).encode()))

    # ----- records ----------------------------------------------------------------------------
    @staticmethod
    def _schema_record(s):
        sid, name, encoding, data = s
        return _record(OP_SCHEMA, struct.pack("<H", sid) + _string(name) + _string(encoding)
                       + struct.pack("<I", len(data)) + data)

    @staticmethod
    def _channel_record(c):
        cid, sid, topic, encoding, metadata = c
        return _record(OP_CHANNEL, struct.pack("<HH", cid, sid) + _string(topic) + _string(encoding)
                       + _map(metadata, lambda k, v: _string(k) + _string(v)))

    def _chunks(self):
        """[(records bytes, start time, end time, {channel: [(time, offset in records)]})]."""
        chunks, records, index, start, end = [], bytearray(), {}, None, None
        counts = {}
        for t, _, cid, data in sorted(self.messages):
            seq = counts.get(cid, 0)
            counts[cid] = seq + 1
            index.setdefault(cid, []).append((t, len(records)))
            records += _record(OP_MESSAGE, struct.pack("<HIQQ", cid, seq, t, t) + data)
            start = t if start is None else start
            end = t
            if len(records) >= CHUNK_BYTES:
                chunks.append((bytes(records), start, end, index))
                records, index, start, end = bytearray(), {}, None, None
        if records:
            chunks.append((bytes(records), start, end, index))
        return chunks, counts

    def finish(self, path):
        """Writes the file; returns {topic: message count}."""
        out = bytearray(MAGIC)
        out += _record(OP_HEADER, _string(self.profile) + _string(self.library))
        for s in self.schemas:
            out += self._schema_record(s)
        for c in self.channels:
            out += self._channel_record(c)
        chunk_indexes = []
        chunks, counts = self._chunks()
        for records, start, end, index in chunks:
            chunk_start = len(out)
            out += _record(OP_CHUNK, struct.pack("<QQQI", start, end, len(records), zlib.crc32(records))
                           + _string("") + struct.pack("<Q", len(records)) + records)
            chunk_length = len(out) - chunk_start
            offsets = []
            index_start = len(out)
            for cid in sorted(index):
                offsets.append((cid, len(out)))
                entries = b"".join(struct.pack("<QQ", t, o) for t, o in index[cid])
                out += _record(OP_MESSAGE_INDEX, struct.pack("<H", cid) + struct.pack("<I", len(entries)) + entries)
            chunk_indexes.append(struct.pack("<QQQQ", start, end, chunk_start, chunk_length)
                                 + _map(offsets, lambda k, v: struct.pack("<HQ", k, v))
                                 + struct.pack("<Q", len(out) - index_start) + _string("")
                                 + struct.pack("<QQ", len(records), len(records)))
        out += _record(OP_DATA_END, struct.pack("<I", zlib.crc32(out)))

        summary_start = len(out)
        groups = []

        def group(op, bodies):
            if bodies:
                groups.append((op, len(out)))
                for b in bodies:
                    out.extend(b)
                groups[-1] = (op, groups[-1][1], len(out) - groups[-1][1])

        group(OP_SCHEMA, [self._schema_record(s) for s in self.schemas])
        group(OP_CHANNEL, [self._channel_record(c) for c in self.channels])
        times = [m[0] for m in self.messages]
        group(OP_STATISTICS, [_record(OP_STATISTICS, struct.pack(
            "<QHIIIIQQ", len(self.messages), len(self.schemas), len(self.channels), 0, 0, len(chunks),
            min(times, default=0), max(times, default=0)) + _map(sorted(counts.items()),
                                                                 lambda k, v: struct.pack("<HQ", k, v)))])
        group(OP_CHUNK_INDEX, [_record(OP_CHUNK_INDEX, b) for b in chunk_indexes])
        summary_offset_start = len(out)
        for op, start, length in groups:
            out += _record(OP_SUMMARY_OFFSET, struct.pack("<BQQ", op, start, length))
        footer_head = struct.pack("<BQ", OP_FOOTER, 8 + 8 + 4) + struct.pack("<QQ", summary_start, summary_offset_start)
        summary_crc = zlib.crc32(bytes(out[summary_start:]) + footer_head)
        out += footer_head + struct.pack("<I", summary_crc)
        out += MAGIC
        part = f"{path}.part"  # renamed when whole: a failed write leaves nothing at path
        try:
            with open(part, "wb") as f:
                f.write(out)
            os.replace(part, path)
        finally:
            if os.path.exists(part):
                os.unlink(part)
        by_id = {c[0]: c[2] for c in self.channels}
        return {by_id[cid]: n for cid, n in counts.items()}
