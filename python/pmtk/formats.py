"""The pmtk container and its formats in numpy (docs/formats.md is the byte-level spec).

A file is a text header (``#?PMTK``, ``KEY=VALUE`` lines, an empty line), the byte-order
marker ``04 03 02 01``, COUNT packed little-endian records of the present channels, and the
XXH3-64 of every byte before it. ``read`` maps the records into a numpy structured array
whose fields are the channels; ``write`` writes such an array back with the same checks a
pmtk reader makes, so that a file this module writes is one every pmtk program reads.
"""

import math
import mmap
import os
import re
import sys
import tempfile

import numpy as np
import xxhash

MAGIC = b"#?PMTK\n"
MARKER = b"\x04\x03\x02\x01"
HEADER_MAX = 1 << 20
LINE_MAX = 1 << 16
COUNT_MAX = 1 << 40
SOFTWARE = "pmtk 0.1.0"

# Value checks (formats/pmfile.h PM_CH_*).
FINITE, NONNEG, UNIT, POSITIVE = "finite", "nonneg", "unit", "positive"

# name -> (title, [(channel, numpy type, components, required, check)]), as formats/*.c.
SCHEMAS = {
    "photons": ("photons file", [
        ("position", "<f4", 3, True, FINITE),
        ("power", "<f4", 3, True, NONNEG),
        ("normal", "<f4", 3, True, UNIT),
        ("direction", "<f4", 3, False, UNIT),
        ("depth", "<u4", 1, True, None),
    ]),
    "photonmap": ("photon map", [
        ("node", "<u4", 2, True, None),
        ("position", "<f4", 3, True, FINITE),
        ("power", "<f4", 3, True, NONNEG),
        ("normal", "<f4", 3, True, UNIT),
        ("direction", "<f4", 3, False, UNIT),
        ("width", "<f4", 1, False, POSITIVE),
    ]),
    "queries": ("queries", [
        ("position", "<f4", 3, True, FINITE),
        ("normal", "<f4", 3, True, UNIT),
        ("weight", "<f4", 3, True, NONNEG),
        ("pixel", "<u4", 1, True, None),
        ("material", "<u2", 1, False, None),
        ("direction", "<f4", 3, False, UNIT),
    ]),
    "radiance": ("radiance buffer", [
        ("rgb", "<f8", 3, True, NONNEG),
        ("variance", "<f8", 3, False, NONNEG),
    ]),
    "aov": ("AOV buffer", [
        ("albedo", "<f4", 3, True, NONNEG),
        ("normal", "<f4", 3, True, FINITE),
        ("depth", "<f4", 1, True, NONNEG),
    ]),
}
OLDEST = {"aov": 2}  # the oldest major version of a format, where it is not OLDEST_MAJOR
MAJOR, OLDEST_MAJOR = 2, 1
CONTAINER_KEYS = ("FORMAT", "VERSION", "BYTE_ORDER", "COUNT", "RECORD_SIZE", "CHANNELS", "BOUNDS")
REPEATED = ("COMMAND", "INPUT")
_KEY = re.compile(rb"^[A-Za-z0-9_.-]+$")
_DIGITS = re.compile(r"^(0|[1-9][0-9]{0,18})$")
_VERSION = re.compile(r"^(0|[1-9][0-9]{0,5})\.(0|[1-9][0-9]{0,6})$")
_CONTROL = re.compile(rb"[\x00-\x1f\x7f]")


class FormatError(ValueError):
    """A file that is not a pmtk file of a known format, or one that fails a check; the
    message names the file and the value, as a pmtk program's does."""


def dtype(fmt, channels):
    """The numpy dtype of a record of format fmt holding the named channels (packed, no
    padding, little-endian), in channel-index order whatever the order given."""
    title, table = _schema(fmt)
    names = set(channels)
    unknown = names - {c[0] for c in table}
    if unknown:
        raise FormatError("%s: no channel %s" % (title, ", ".join(sorted(unknown))))
    return np.dtype([(n, t) if k == 1 else (n, t, (k,)) for n, t, k, _, _ in table if n in names])


def _schema(fmt):
    if fmt not in SCHEMAS:
        raise FormatError("unknown format '%s' (known: %s)" % (fmt, " ".join(SCHEMAS)))
    return SCHEMAS[fmt]


class PmFile:
    """One pmtk file: ``format``, ``header`` (a dict: COMMAND and INPUT are lists of their
    lines, any other repeated key a list too, every other key its string), ``records`` (a
    numpy structured array, one field per present channel, memory-mapped when read from a
    regular file), ``checksum`` (the content hash as read, an int) and ``path``."""

    def __init__(self, fmt, header, records, checksum=None, path=None, header_text=None):
        self.format = fmt
        self.header = header
        self.records = records
        self.checksum = checksum
        self.path = path
        self._text = header_text  # the header bytes as read, kept while header is unchanged
        self._as_read = _header_copy(header) if header_text is not None else None

    @property
    def channels(self):
        return list(self.records.dtype.names)

    def __len__(self):
        return len(self.records)

    def __repr__(self):
        return "<pmtk %s %r: %d records, channels %s>" % (self.format, self.path, len(self), " ".join(self.channels))


def _header_copy(h):
    return {k: list(v) if isinstance(v, list) else v for k, v in h.items()}


def _fail(title, name, what):
    raise FormatError("%s '%s': %s" % (title, name, what))


def _parse_header(buf, name):
    """(header dict, header text length) of the bytes buf, checked as docs/formats.md §2.2
    and §2.3 say."""
    if bytes(buf[:7]) != MAGIC:
        raise FormatError("'%s': not a pmtk file (no #?PMTK magic line)" % name)
    end = bytes(buf[: HEADER_MAX + 1]).find(b"\n\n", 6)
    if end < 0 and len(buf) <= HEADER_MAX:
        raise FormatError("'%s': truncated header: no empty line in its %d bytes" % (name, len(buf)))
    if end < 0:
        raise FormatError("'%s': header has no empty line within %d bytes (truncated or not pmtk)" % (name, HEADER_MAX))
    text = bytes(buf[: end + 2])
    if len(text) > HEADER_MAX:
        raise FormatError("'%s': header longer than %d bytes" % (name, HEADER_MAX))
    if b"\x00" in text:
        raise FormatError("'%s': NUL byte in the header" % name)
    header = {}
    for n, line in enumerate(text[7:-2].split(b"\n"), start=2):
        if len(line) > LINE_MAX:
            raise FormatError("'%s': header line %d longer than %d bytes" % (name, n, LINE_MAX))
        key, eq, value = line.partition(b"=")
        if not eq or not _KEY.match(key):
            raise FormatError("'%s': malformed header line %d '%s'" % (name, n, line[:80].decode("utf-8", "replace")))
        if _CONTROL.search(value):
            raise FormatError("'%s': control byte in the value of %s" % (name, key.decode()))
        k, v = key.decode("ascii"), value.decode("utf-8", "surrogateescape")
        if k in REPEATED:
            header.setdefault(k, []).append(v)
        elif k in header:
            if k in CONTAINER_KEYS or k == "CHANNEL_MASK":
                raise FormatError("'%s': %s given twice" % (name, k))
            if not isinstance(header[k], list):
                header[k] = [header[k]]
            header[k].append(v)
        else:
            header[k] = v
    return header, len(text)


def _layout(header, name):
    """(format, title, channel names, count, record size) from a parsed header."""
    for k in CONTAINER_KEYS:
        if k not in header:
            raise FormatError("'%s': header lacks %s" % (name, k))
    fmt = header["FORMAT"]
    if fmt not in SCHEMAS:
        raise FormatError("'%s': unknown FORMAT '%s'" % (name, fmt))
    title, table = SCHEMAS[fmt]
    m = _VERSION.match(header["VERSION"])
    if not m:
        _fail(title, name, "malformed VERSION '%s'" % header["VERSION"])
    major, oldest = int(m.group(1)), OLDEST.get(fmt, OLDEST_MAJOR)
    if major > MAJOR or major < oldest:
        _fail(title, name, "version %s not supported (this reader reads %d.x to %d.x)" % (header["VERSION"], oldest, MAJOR))
    if header["BYTE_ORDER"] != "little-endian":
        _fail(title, name, "BYTE_ORDER '%s' is not little-endian" % header["BYTE_ORDER"])
    nums = {}
    for k in ("COUNT", "RECORD_SIZE"):
        if not _DIGITS.match(header[k]):
            _fail(title, name, "malformed %s '%s'" % (k, header[k]))
        nums[k] = int(header[k])
    if nums["COUNT"] > COUNT_MAX:
        _fail(title, name, "COUNT %d above %d" % (nums["COUNT"], COUNT_MAX))
    names = header["CHANNELS"].split(" ")
    order = [c[0] for c in table]
    if any(n not in order for n in names):
        _fail(title, name, "CHANNELS '%s' names a channel unknown to %s" % (header["CHANNELS"], fmt))
    if [n for n in order if n in names] != names:
        _fail(title, name, "malformed CHANNELS '%s' (each channel once, in the order %s)" % (header["CHANNELS"], " ".join(order)))
    missing = [c[0] for c in table if c[3] and c[0] not in names]
    if missing:
        _fail(title, name, "lacks required channel %s" % missing[0])
    if major == 1:
        mask = sum(1 << i for i, c in enumerate(table) if c[0] in names)
        if header.get("CHANNEL_MASK") != "0x%08x" % mask:
            _fail(title, name, "CHANNEL_MASK '%s' disagrees with CHANNELS (0x%08x)" % (header.get("CHANNEL_MASK"), mask))
    elif "CHANNEL_MASK" in header:
        _fail(title, name, "a version-%d header has CHANNEL_MASK" % major)
    dt = dtype(fmt, names)
    if nums["RECORD_SIZE"] != dt.itemsize:
        _fail(title, name, "RECORD_SIZE %d but the channels make %d" % (nums["RECORD_SIZE"], dt.itemsize))
    bounds = header["BOUNDS"].split(" ")
    try:
        b = [float(x) for x in bounds]
    except ValueError:
        b = []
    if len(b) != 6 or not all(math.isfinite(x) and abs(x) <= 3.4e38 for x in b) or any(b[i] > b[i + 3] for i in range(3)):
        _fail(title, name, "malformed BOUNDS '%s'" % header["BOUNDS"])
    return fmt, title, dt, nums["COUNT"]


def _bad(title, name, what):
    raise FormatError("bad value in %s '%s': %s" % (title, name, what))


def _image_size(header, title, name):
    size = []
    for k in ("width", "height"):
        v = header.get(k)
        if not isinstance(v, str) or not _DIGITS.match(v) or not 1 <= int(v) <= 65536:
            _fail(title, name, "%s '%s' not a whole number in 1..65536" % (k, v))
        size.append(int(v))
    if size[0] * size[1] > 1 << 26:
        _fail(title, name, "image size %dx%d above %d pixels" % (size[0], size[1], 1 << 26))
    return size


def _quick_ok(v, check):
    """True when every value of channel array v passes check, by reductions over one
    contiguous copy (NaN propagates through min and max); False sends the caller to the exact
    per-record test, which finds the record to name."""
    c = np.ascontiguousarray(v)
    if check == UNIT:
        # f32 sums are within 1e-6 of the f64 ones: only values near the bound need f64
        return bool(np.abs(np.einsum("ij,ij->i", c, c) - 1).max() <= 1.99e-3)
    lo, hi = c.min(), c.max()
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return False
    return check == FINITE or (check == NONNEG and lo >= 0) or (check == POSITIVE and lo > 0)


def check_records(fmt, header, records, name="records"):
    """Raises FormatError at the first value a pmtk reader would refuse: NaN or Inf, a
    negative power, a normal that is not unit length, a pixel outside the image, a material
    outside the table, a radiance buffer whose COUNT is not width x height. The photon map's
    tree is not walked here (pm-info checks it)."""
    title, table = _schema(fmt)
    for ch, _, _, _, check in table:
        if ch not in records.dtype.names or check is None or len(records) == 0:
            continue
        v = records[ch]
        if _quick_ok(v, check):
            continue
        if check == UNIT:
            v64 = v.astype(np.float64)
            bad = ~(np.abs((v64 * v64).sum(axis=-1) - 1.0) <= 2e-3)
        elif check == FINITE:
            bad = ~np.isfinite(v).reshape(len(v), -1).all(axis=1)
        elif check == NONNEG:
            bad = ~(v >= 0).reshape(len(v), -1).all(axis=1)
            bad |= ~np.isfinite(v).reshape(len(v), -1).all(axis=1)
        else:
            bad = ~((v > 0) & np.isfinite(v))
        if bad.any():
            i = int(np.argmax(bad))
            _bad(title, name, "record %d channel %s is %s, not %s" % (i, ch, v[i].tolist(), {
                UNIT: "a unit vector", FINITE: "finite", NONNEG: "finite and >= 0", POSITIVE: "finite and > 0"}[check]))
    if fmt in ("queries", "radiance", "aov"):
        w, h = _image_size(header, title, name)
        if fmt != "queries" and len(records) != w * h:
            _fail(title, name, "COUNT %d is not width x height = %d" % (len(records), w * h))
        if fmt == "queries":
            if len(records) and int(records["pixel"].max()) >= w * h:
                i = int(np.argmax(records["pixel"] >= w * h))
                _bad(title, name, "record %d pixel %d outside the %dx%d image" % (i, int(records["pixel"][i]), w, h))
            nm = header.get("materials")
            if not isinstance(nm, str) or not _DIGITS.match(nm) or not 1 <= int(nm) <= 65536:
                _fail(title, name, "materials '%s' not a whole number in 1..65536" % nm)
            if int(nm) > 1 and "material" not in records.dtype.names:
                _fail(title, name, "%s materials but no material channel" % nm)
            if "material" in records.dtype.names and len(records) and int(records["material"].max()) >= int(nm):
                i = int(np.argmax(records["material"] >= int(nm)))
                _bad(title, name, "record %d material %d outside the table of %s" % (i, int(records["material"][i]), nm))


def read(path, verify=True):
    """Reads the pmtk file at path ('-' is stdin) and returns a PmFile. The records of a
    regular file are memory-mapped (read-only), not copied. verify=True (the default)
    checks the checksum and every value as a pmtk reader does; a bad file raises
    FormatError naming the file and the value."""
    name = "stdin" if path == "-" else os.fspath(path)
    if path == "-":
        buf = memoryview(sys.stdin.buffer.read())
        mm = None
    else:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size == 0:
                raise FormatError("'%s': empty file, not a pmtk file" % name)
            mm = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        buf = memoryview(mm)
    header, hlen = _parse_header(buf, name)
    fmt, title, dt, count = _layout(header, name)
    want = hlen + 4 + count * dt.itemsize + 8
    if len(buf) < want:
        _fail(title, name, "truncated: %d bytes, the header says %d (COUNT %d)" % (len(buf), want, count))
    if len(buf) > want:
        extra = bytes(buf[want:want + 7])
        _fail(title, name, "%d bytes after the checksum%s" % (len(buf) - want, " (a stream of documents: use pmtk.read_stream)" if extra == MAGIC else ""))
    marker = bytes(buf[hlen:hlen + 4])
    if marker != MARKER:
        _fail(title, name, "byte-order marker %s is not 04 03 02 01%s" % (marker.hex(" "), " (big-endian)" if marker == MARKER[::-1] else ""))
    stored = int.from_bytes(buf[want - 8:want], "little")
    if verify:
        computed = xxhash.xxh3_64_intdigest(buf[: want - 8])
        if computed != stored:
            _fail(title, name, "checksum mismatch: stored xxh3:%016x, computed xxh3:%016x" % (stored, computed))
    if count == 0:
        records = np.zeros(0, dtype=dt)
    else:
        records = np.frombuffer(buf, dtype=dt, count=count, offset=hlen + 4)
    if verify:
        check_records(fmt, header, records, name)
    text = bytes(buf[:hlen])
    del buf  # the array keeps the map alive
    return PmFile(fmt, header, records, stored, name, text)


def read_stream(path):
    """Yields each document of a stream of documents (docs/formats.md §2.6a) as a PmFile,
    read into memory and checked; a document is named 'PATH, frame N'."""
    data = sys.stdin.buffer.read() if path == "-" else open(path, "rb").read()
    name = "stdin" if path == "-" else os.fspath(path)
    pos, frame = 0, 0
    while pos < len(data):
        doc = f"{name}, frame {frame}"
        header, hlen = _parse_header(memoryview(data)[pos:], doc)
        _, _, dt, count = _layout(header, doc)
        end = pos + hlen + 4 + count * dt.itemsize + 8
        if end > len(data):
            raise FormatError("'%s': truncated document" % doc)
        yield _read_bytes(data[pos:end], doc)
        pos, frame = end, frame + 1


def _read_bytes(data, name):
    header, hlen = _parse_header(data, name)
    fmt, title, dt, count = _layout(header, name)
    stored = int.from_bytes(data[-8:], "little")
    if data[hlen:hlen + 4] != MARKER:
        _fail(title, name, "byte-order marker is not 04 03 02 01")
    computed = xxhash.xxh3_64_intdigest(data[:-8])
    if computed != stored:
        _fail(title, name, "checksum mismatch: stored xxh3:%016x, computed xxh3:%016x" % (stored, computed))
    records = np.frombuffer(data, dtype=dt, count=count, offset=hlen + 4) if count else np.zeros(0, dtype=dt)
    check_records(fmt, header, records, name)
    return PmFile(fmt, header, records, stored, name, data[:hlen])


def _format_header(fmt, header, records):
    """The header text a pmtk writer writes (docs/formats.md §2.4) for records."""
    h = dict(header)
    bounds = h.get("BOUNDS", "0 0 0 0 0 0")
    lines = ["FORMAT=" + fmt, "VERSION=%d.0" % MAJOR, "BYTE_ORDER=little-endian", "COUNT=%d" % len(records),
             "RECORD_SIZE=%d" % records.dtype.itemsize, "CHANNELS=" + " ".join(records.dtype.names),
             "BOUNDS=" + bounds, "SOFTWARE=" + SOFTWARE]
    lines += ["COMMAND=" + c for c in _as_list(h.get("COMMAND", []))]
    skip = set(CONTAINER_KEYS) | {"SOFTWARE", "COMMAND", "CHANNEL_MASK"}
    for k, v in h.items():
        if k in skip:
            continue
        if not _KEY.match(k.encode("ascii", "replace")):
            raise FormatError("header key '%s' is not of [A-Za-z0-9_.-]" % k)
        for one in _as_list(v):
            lines.append(k + "=" + re.sub(r"[\x00-\x1f\x7f]", " ", str(one)))
    text = ("\n".join(["#?PMTK"] + lines) + "\n\n").encode("utf-8", "surrogateescape")
    if len(text) > HEADER_MAX or any(len(line) > LINE_MAX for line in text.split(b"\n")):
        raise FormatError("header too long for a pmtk reader")
    return text


def _as_list(v):
    return v if isinstance(v, list) else [v]


def write(path, data, header=None, fmt=None):
    """Writes a pmtk file to path ('-' is stdout), atomically (a temporary file renamed into
    place). data is a PmFile, or a numpy structured array of a format's channels with
    header (a dict) and fmt (the FORMAT, or header['FORMAT']). A PmFile read and written
    back unchanged gives the same bytes. The records are checked first: a value a pmtk
    reader would refuse raises FormatError and writes nothing."""
    if isinstance(data, PmFile):
        fmt, header, records = data.format, data.header, data.records
        text = data._text if data._as_read is not None and data._as_read == header else None
    else:
        header = dict(header or {})
        fmt = fmt or header.get("FORMAT")
        if fmt is None:
            raise FormatError("write: no format given (fmt= or header['FORMAT'])")
        records, text = data, None
    _schema(fmt)
    want = dtype(fmt, records.dtype.names)
    if records.dtype != want:
        records = _convert(records, want)
    title, table = SCHEMAS[fmt]
    missing = [c[0] for c in table if c[3] and c[0] not in records.dtype.names]
    if missing:
        raise FormatError("refusing to write %s '%s': no %s channel" % (title, path, missing[0]))
    if text is not None and int(header["COUNT"]) != len(records):
        text = None
    check_records(fmt, header, records, "stdout" if path == "-" else os.fspath(path))
    if text is None:
        text = _format_header(fmt, header, records)
    body = text + MARKER + np.ascontiguousarray(records).tobytes()
    body += xxhash.xxh3_64_intdigest(body).to_bytes(8, "little")
    if path == "-":
        sys.stdout.buffer.write(body)
        sys.stdout.buffer.flush()
        return
    path = os.fspath(path)
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", dir=os.path.dirname(path) or ".")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(body)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        os.unlink(tmp)
        raise


def _umask():
    m = os.umask(0)
    os.umask(m)
    return m


def _convert(records, want):
    out = np.empty(len(records), dtype=want)
    for n in want.names:
        out[n] = records[n]
    return out


def empty(fmt, count, channels=None, **keys):
    """A zeroed structured array of count records of format fmt (its required channels, or
    the named ones) and a header dict holding FORMAT, BOUNDS and the keys given, ready for
    filling and write(path, records, header)."""
    _, table = _schema(fmt)
    names = channels or [c[0] for c in table if c[3]]
    header = {"FORMAT": fmt, "BOUNDS": "0 0 0 0 0 0"}
    header.update({k.replace("_", "."): str(v) for k, v in keys.items()})
    return np.zeros(count, dtype=dtype(fmt, names)), header
