"""The table reader's compiled kernel: one pass over a window of a JSON array of records that checks the grammar
as Python's json does and writes every field straight into typed column streams.

Longer than our ~300-line norm on purpose: it is one state machine (the grammar, strings, numbers, the records'
fields) that only makes sense read together; the Python side (`sources/table_scan.py`, `table_typing.py`) does
everything else.

What it does, per record of the window (`scan`):
- the grammar of Python's json (`json.loads`): whitespace, strings (escapes decoded, raw control characters
  refused, UTF-8 validated as Python's decoder does; `\\u` surrogate pairs joined, a lone surrogate refused: no
  UTF-8 column can hold it), numbers (`-?(0|[1-9]\\d*)(\\.\\d+)?([eE][-+]?\\d+)?`), `true false null NaN Infinity
  -Infinity`, no trailing commas, nothing but whitespace after the array;
- each key looked up among the table's fields (a key it does not know stops the scan: the caller adds it as an
  extra field and scans the record again), a repeated key noted, the record's key order as a layout id;
- each value by its field's class: strings into a byte stream, integers parsed exactly (beyond int64: kept as
  text), float literals as text (Arrow's correctly rounded parser types them after), lists of numbers flattened with
  each element's literal kind, lists of strings, and a field it does not type (an extra) as its raw JSON text.
  A value of another JSON type is only classified (`kinds`) and skipped: the caller names the record.

The caller owns every output array; a stream that is full, or a record cut by the end of the window, makes the scan
stop at the start of that record with everything it wrote for it undone (`FULL`, `MORE`): the caller grows the
stream or reads more and calls again from there.

Every function is compiled with `_nrt=False`: nothing here allocates (work arrays, the layout hash table and the
streams come from the caller), and without it half the time went to the atomic reference counts numba keeps on every
array handed to a helper (perf). Streams of one dtype are regions of one array (`st8`, `st64`: array, bases,
capacities, counts), and copies are loops: numba copies the source of a slice assignment first.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# What a field's value was, per record and field (`kinds`).
ABSENT, NULL, FALSE, TRUE, INT, BIGINT, FLOAT, STRING, ARRAY, OBJECT = range(10)
LIST_OK, LIST_BAD, LIST_SHAPE, TOO_LONG = 10, 11, 12, 13

# Field classes (`spec[f, CLASS]`).
C_STRING, C_INT, C_BOOL, C_FLOATS, C_MATRIX, C_STRINGS, C_RAW = range(7)
# Columns of `spec`: the class, then stream ids (-1: none) and the name's place in `names`.
CLASS, DATA, OFFSETS, VALUES, ELEMENTS, FLAGS, NAME_START, NAME_END = range(8)

# Statuses (`io[STATUS]`).
DONE, MORE, FULL, NEW_KEY, ERROR = range(5)
# `io` slots.
POS, RECORDS, STATE, STATUS, ERR_POS, ERR_CODE, ARG0, ARG1, FILE_OFFSET, MAX_STRING, LAYOUTS = range(11)
# Top-level states: after "[", after a record, after ",", after "]".
S_FIRST, S_AFTER, S_NEXT, S_END = range(4)

# Error codes (`io[ERR_CODE]`), worded by the caller.
E_EOF, E_VALUE, E_DELIM_ARRAY, E_DELIM_OBJECT, E_KEY, E_COLON, E_CONTROL, E_ESCAPE, E_UTF8, E_SURROGATE = range(10)
E_NUMBER, E_EXTRA_DATA, E_DEPTH, E_TRAILING_COMMA, E_LAYOUTS = range(10, 15)

MAX_DEPTH = 900  # nesting inside one field's value: Python's json (the devkit, export-json) stops near 1,000
MAX_LAYOUTS = 65535  # distinct key orders of one table (`_layout` is uint16)

# true, false, null, NaN, Infinity, end to end; _WORD_ENDS[start] is the length of the word starting there
_WORDS = np.frombuffer(b"truefalsenullNaNInfinity", np.uint8).copy()
_WORD_ENDS = np.zeros(len(_WORDS), np.int64)
_WORD_ENDS[[0, 4, 9, 13, 16]] = [4, 5, 4, 3, 8]


@njit(cache=True, inline="always", _nrt=False)
def _skip_ws(buf, p, end):
    while p < end and (buf[p] == 32 or buf[p] == 10 or buf[p] == 13 or buf[p] == 9):
        p += 1
    return p


@njit(cache=True, _nrt=False)
def _hex(b):
    if 48 <= b <= 57:
        return b - 48
    if 97 <= b <= 102:
        return b - 87
    if 65 <= b <= 70:
        return b - 55
    return -1


@njit(cache=True, _nrt=False)
def _u4(buf, p):
    v = 0
    for k in range(4):
        h = _hex(buf[p + k])
        if h < 0:
            return -1
        v = v * 16 + h
    return v


@njit(cache=True, _nrt=False)
def _string(buf, p, end, out, o, cap, limit, io):
    """The string whose opening quote is at p-1, decoded into out[o:] (out None-like when cap < 0: check only).
    Returns (position after the closing quote, bytes written) or (-1, MORE/FULL/ERROR) with io set on ERROR.
    Over `limit` bytes the rest is checked but not written, and the length is returned negated."""
    n = 0
    copy = cap >= 0
    while True:
        q = p  # plain bytes up to the next quote, backslash, control or non-ASCII byte: one copy
        while q < end:
            c = buf[q]
            if c == 34 or c == 92 or c < 32 or c >= 128:
                break
            q += 1
        if q > p:
            if copy and n < limit:
                take = min(q - p, limit - n)
                if o + n + take > cap:
                    return -1, FULL
                for i in range(take):  # a loop: numba copies the source of a slice assignment first
                    out[o + n + i] = buf[p + i]
            n += q - p
            p = q
        if p >= end:
            return -1, MORE
        b = buf[p]
        if b == 34:
            return p + 1, n
        if b == 92:
            if p + 1 >= end:
                return -1, MORE
            e = buf[p + 1]
            c = -1
            if e == 34 or e == 92 or e == 47:
                c = e
            elif e == 98:
                c = 8
            elif e == 102:
                c = 12
            elif e == 110:
                c = 10
            elif e == 114:
                c = 13
            elif e == 116:
                c = 9
            elif e == 117:
                if p + 6 > end:
                    return -1, MORE
                c = _u4(buf, p + 2)
                if c < 0:  # Python names the "u"
                    io[ERR_POS], io[ERR_CODE] = p + 1, E_ESCAPE
                    return -1, ERROR
                if 0xD800 <= c <= 0xDBFF:
                    low = -1
                    for ahead in range(6, 12):  # a low surrogate's escape must follow; say so as soon as it does not
                        if p + ahead >= end:
                            return -1, MORE
                        if (ahead == 6 and buf[p + 6] != 92) or (ahead == 7 and buf[p + 7] != 117):
                            break
                    else:
                        low = _u4(buf, p + 8)
                    if not 0xDC00 <= low <= 0xDFFF:
                        io[ERR_POS], io[ERR_CODE] = p, E_SURROGATE
                        return -1, ERROR
                    c = 0x10000 + ((c - 0xD800) << 10) + (low - 0xDC00)
                    p += 6
                elif 0xDC00 <= c <= 0xDFFF:
                    io[ERR_POS], io[ERR_CODE] = p, E_SURROGATE
                    return -1, ERROR
                p += 4
            else:
                io[ERR_POS], io[ERR_CODE] = p, E_ESCAPE
                return -1, ERROR
            p += 2
            # UTF-8 of code point c
            size = 1 if c < 0x80 else (2 if c < 0x800 else (3 if c < 0x10000 else 4))
            if copy and n + size <= limit:
                if o + n + size > cap:
                    return -1, FULL
                if size == 1:
                    out[o + n] = c
                elif size == 2:
                    out[o + n] = 0xC0 | (c >> 6)
                    out[o + n + 1] = 0x80 | (c & 0x3F)
                elif size == 3:
                    out[o + n] = 0xE0 | (c >> 12)
                    out[o + n + 1] = 0x80 | ((c >> 6) & 0x3F)
                    out[o + n + 2] = 0x80 | (c & 0x3F)
                else:
                    out[o + n] = 0xF0 | (c >> 18)
                    out[o + n + 1] = 0x80 | ((c >> 12) & 0x3F)
                    out[o + n + 2] = 0x80 | ((c >> 6) & 0x3F)
                    out[o + n + 3] = 0x80 | (c & 0x3F)
            n += size
            continue
        if b < 32:
            io[ERR_POS], io[ERR_CODE] = p, E_CONTROL
            return -1, ERROR
        size = 1
        if b >= 128:  # a UTF-8 sequence, validated as Python's strict decoder does
            if 0xC2 <= b <= 0xDF:
                size = 2
            elif 0xE0 <= b <= 0xEF:
                size = 3
            elif 0xF0 <= b <= 0xF4:
                size = 4
            else:
                io[ERR_POS], io[ERR_CODE] = p, E_UTF8
                return -1, ERROR
            if p + size > end:
                return -1, MORE
            lo, hi = 0x80, 0xBF
            if b == 0xE0:
                lo = 0xA0
            elif b == 0xED:
                hi = 0x9F
            elif b == 0xF0:
                lo = 0x90
            elif b == 0xF4:
                hi = 0x8F
            if not lo <= buf[p + 1] <= hi:
                io[ERR_POS], io[ERR_CODE] = p, E_UTF8
                return -1, ERROR
            for k in range(2, size):
                if not 0x80 <= buf[p + k] <= 0xBF:
                    io[ERR_POS], io[ERR_CODE] = p, E_UTF8
                    return -1, ERROR
        if copy and n + size <= limit:
            if o + n + size > cap:
                return -1, FULL
            for k in range(size):
                out[o + n + k] = buf[p + k]
        n += size
        p += size


@njit(cache=True, _nrt=False)
def _number(buf, p, end, io):
    """The number starting at p. Returns (end, kind INT/BIGINT/FLOAT, int value) or (-1, MORE/ERROR, 0)."""
    start = p
    neg = False
    if buf[p] == 45:
        neg = True
        p += 1
        if p >= end:
            return -1, MORE, 0
        if buf[p] == 73:  # -Infinity
            if p + 8 > end:
                return -1, MORE, 0
            if buf[p + 1] == 110 and buf[p + 2] == 102 and buf[p + 3] == 105 and buf[p + 4] == 110 and \
                    buf[p + 5] == 105 and buf[p + 6] == 116 and buf[p + 7] == 121:
                return p + 8, FLOAT, 0
            io[ERR_POS], io[ERR_CODE] = start, E_VALUE
            return -1, ERROR, 0
    if p >= end:
        return -1, MORE, 0
    b = buf[p]
    if b == 48:
        p += 1
    elif 49 <= b <= 57:
        while p < end and 48 <= buf[p] <= 57:
            p += 1
    else:
        io[ERR_POS], io[ERR_CODE] = start, E_VALUE
        return -1, ERROR, 0
    digits_end = p
    kind = INT
    if p < end and buf[p] == 46:
        p += 1
        if p >= end:
            return -1, MORE, 0
        if not 48 <= buf[p] <= 57:  # "1." : Python reads 1, then stops at "."
            io[ERR_POS], io[ERR_CODE] = p - 1, E_NUMBER
            return -1, ERROR, 0
        while p < end and 48 <= buf[p] <= 57:
            p += 1
        kind = FLOAT
    if p < end and (buf[p] == 101 or buf[p] == 69):
        q = p + 1
        if q < end and (buf[q] == 43 or buf[q] == 45):
            q += 1
        if q >= end:
            return -1, MORE, 0
        if 48 <= buf[q] <= 57:  # else Python reads the number without the "e", then stops at it
            while q < end and 48 <= buf[q] <= 57:
                q += 1
            p = q
            kind = FLOAT
        else:
            io[ERR_POS], io[ERR_CODE] = p, E_NUMBER
            return -1, ERROR, 0
    if p >= end:
        return -1, MORE, 0
    if kind == FLOAT:
        return p, FLOAT, 0
    first = start + 1 if neg else start
    n_digits = digits_end - first
    if n_digits > 19:
        return p, BIGINT, 0
    mag = np.uint64(0)
    for k in range(first, digits_end):
        mag = mag * np.uint64(10) + np.uint64(buf[k] - 48)
    limit = np.uint64(9223372036854775808) if neg else np.uint64(9223372036854775807)
    if mag > limit:
        return p, BIGINT, 0
    if neg:
        if mag == np.uint64(9223372036854775808):
            return p, INT, np.int64(-9223372036854775807 - 1)
        return p, INT, -np.int64(mag)
    return p, INT, np.int64(mag)


@njit(cache=True, _nrt=False)
def _word(buf, p, end, io):
    """true/false/null/NaN/Infinity at p: (end, kind) or (-1, MORE/ERROR)."""
    b = buf[p]
    if b == 116:
        start, kind = 0, TRUE
    elif b == 102:
        start, kind = 4, FALSE
    elif b == 110:
        start, kind = 9, NULL
    elif b == 78:
        start, kind = 13, FLOAT
    else:
        start, kind = 16, FLOAT
    n = _WORD_ENDS[start]
    for k in range(n):
        if p + k >= end:
            return -1, MORE
        if buf[p + k] != _WORDS[start + k]:
            io[ERR_POS], io[ERR_CODE] = p, E_VALUE
            return -1, ERROR
    return p + n, kind


@njit(cache=True, _nrt=False)
def _skip(buf, p, end, io, stack):
    """Check and skip one JSON value at p (any nesting up to MAX_DEPTH). Returns (end, JSON kind) or (-1, status)."""
    depth = 0
    kind = NULL
    expect_value = True
    while True:
        p = _skip_ws(buf, p, end)
        if p >= end:
            return -1, MORE
        b = buf[p]
        if expect_value:
            if b == 123 or b == 91:
                if depth == 0:
                    kind = OBJECT if b == 123 else ARRAY
                if depth >= MAX_DEPTH:
                    io[ERR_POS], io[ERR_CODE] = p, E_DEPTH
                    return -1, ERROR
                stack[depth] = b
                depth += 1
                p = _skip_ws(buf, p + 1, end)
                if p >= end:
                    return -1, MORE
                if (b == 123 and buf[p] == 125) or (b == 91 and buf[p] == 93):
                    depth -= 1
                    p += 1
                    expect_value = False
                    if depth == 0:
                        return p, kind
                    continue
                if b == 123:  # a key first
                    if buf[p] != 34:
                        io[ERR_POS], io[ERR_CODE] = p, E_KEY
                        return -1, ERROR
                    q, st = _string(buf, p + 1, end, buf, 0, -1, 0, io)
                    if q < 0:
                        return -1, st
                    q = _skip_ws(buf, q, end)
                    if q >= end:
                        return -1, MORE
                    if buf[q] != 58:
                        io[ERR_POS], io[ERR_CODE] = q, E_COLON
                        return -1, ERROR
                    p = q + 1
                continue
            if b == 34:
                q, st = _string(buf, p + 1, end, buf, 0, -1, 0, io)
                if q < 0:
                    return -1, st
                p = q
                if depth == 0:
                    return p, STRING
            elif b == 45 or 48 <= b <= 57:
                q, k, _ = _number(buf, p, end, io)
                if q < 0:
                    return -1, k
                p = q
                if depth == 0:
                    return p, k
            elif b == 116 or b == 102 or b == 110 or b == 78 or b == 73:
                q, k = _word(buf, p, end, io)
                if q < 0:
                    return -1, k
                p = q
                if depth == 0:
                    return p, k
            else:
                io[ERR_POS], io[ERR_CODE] = p, E_VALUE
                return -1, ERROR
            expect_value = False
            continue
        # after a value inside a container
        top = stack[depth - 1]
        if b == 44:
            p = _skip_ws(buf, p + 1, end)
            if p >= end:
                return -1, MORE
            if top == 123:
                if buf[p] != 34:
                    io[ERR_POS], io[ERR_CODE] = p, E_TRAILING_COMMA if buf[p] == 125 else E_KEY
                    return -1, ERROR
                q, st = _string(buf, p + 1, end, buf, 0, -1, 0, io)
                if q < 0:
                    return -1, st
                q = _skip_ws(buf, q, end)
                if q >= end:
                    return -1, MORE
                if buf[q] != 58:
                    io[ERR_POS], io[ERR_CODE] = q, E_COLON
                    return -1, ERROR
                p = q + 1
            elif buf[p] == 93:
                io[ERR_POS], io[ERR_CODE] = p, E_TRAILING_COMMA
                return -1, ERROR
            expect_value = True
        elif (top == 123 and b == 125) or (top == 91 and b == 93):
            depth -= 1
            p += 1
            if depth == 0:
                return p, kind
        else:
            io[ERR_POS], io[ERR_CODE] = p, E_DELIM_OBJECT if top == 123 else E_DELIM_ARRAY
            return -1, ERROR


@njit(cache=True, inline="always", _nrt=False)
def _room(st, sid, extra, io, which):
    """Whether stream `sid` of `st` (array, bases, capacities, counts) has room for `extra` more items; if not, io
    names it (ARG0, ARG1: 0 bytes, 1 int64)."""
    if st[3][sid] + extra <= st[2][sid]:
        return True
    io[ARG0], io[ARG1] = sid, which
    return False


@njit(cache=True, _nrt=False)
def _full(io, sid, which):
    io[ARG0], io[ARG1] = sid, which
    return FULL


@njit(cache=True, inline="always", _nrt=False)
def _copy(st8, sid, buf, p, n):
    """buf[p:p+n] appended to byte stream `sid` (room checked by the caller)."""
    at = st8[1][sid] + st8[3][sid]
    out = st8[0]
    for i in range(n):  # a loop: numba copies the source of a slice assignment first
        out[at + i] = buf[p + i]
    st8[3][sid] += n


@njit(cache=True, inline="always", _nrt=False)
def _push(st64, sid, value):
    st64[0][st64[1][sid] + st64[3][sid]] = value
    st64[3][sid] += 1


@njit(cache=True, _nrt=False)
def _list(buf, p, end, io, f, spec, st8, st64, matrix, strings, limit, stack):
    """The list field value at p (buf[p] == '['): elements into the field's streams. (end, kind) or (-1, status)."""
    data, elements, flags = spec[f, DATA], spec[f, ELEMENTS], spec[f, FLAGS]
    p = _skip_ws(buf, p + 1, end)
    if p >= end:
        return -1, MORE
    kind = LIST_OK
    inner = 0
    if buf[p] == 93:
        return p + 1, kind
    while True:
        p = _skip_ws(buf, p, end)
        if p >= end:
            return -1, MORE
        b = buf[p]
        if matrix and b == 91:  # an inner row of numbers
            inner += 1
            q = _skip_ws(buf, p + 1, end)
            if q >= end:
                return -1, MORE
            count = 0
            if buf[q] == 93:
                q += 1
            else:
                while True:
                    q = _skip_ws(buf, q, end)
                    if q >= end:
                        return -1, MORE
                    c = buf[q]
                    if c == 45 or 48 <= c <= 57 or c == 78 or c == 73:
                        r, k = _element_number(buf, q, end, io, data, elements, flags, st8, st64)
                        if r < 0:
                            return -1, k
                        count += 1
                    else:
                        r, k = _skip(buf, q, end, io, stack)
                        if r < 0:
                            return -1, k
                        kind = LIST_BAD
                    q = _skip_ws(buf, r, end)
                    if q >= end:
                        return -1, MORE
                    if buf[q] == 44:
                        q += 1
                        q2 = _skip_ws(buf, q, end)
                        if q2 >= end:
                            return -1, MORE
                        if buf[q2] == 93:
                            io[ERR_POS], io[ERR_CODE] = q2, E_TRAILING_COMMA
                            return -1, ERROR
                    elif buf[q] == 93:
                        q += 1
                        break
                    else:
                        io[ERR_POS], io[ERR_CODE] = q, E_DELIM_ARRAY
                        return -1, ERROR
            if count != 3 and kind == LIST_OK:
                kind = LIST_SHAPE
            p = q
        elif (not matrix and not strings) and (b == 45 or 48 <= b <= 57 or b == 78 or b == 73):
            r, k = _element_number(buf, p, end, io, data, elements, flags, st8, st64)
            if r < 0:
                return -1, k
            p = r
        elif strings and b == 34:
            base = st8[1][data]
            q, written = _string(buf, p + 1, end, st8[0], base + st8[3][data], base + st8[2][data], limit, io)
            if q < 0:
                return -1, _full(io, data, 0) if written == FULL else written
            if written > limit:
                kind = TOO_LONG
            else:
                st8[3][data] += written
            if not _room(st64, elements, 1, io, 1):
                return -1, FULL
            _push(st64, elements, st8[3][data])
            p = q
        else:
            r, k = _skip(buf, p, end, io, stack)
            if r < 0:
                return -1, k
            if kind == LIST_OK or kind == LIST_SHAPE:
                kind = LIST_BAD
            p = r
        p = _skip_ws(buf, p, end)
        if p >= end:
            return -1, MORE
        if buf[p] == 44:
            p = _skip_ws(buf, p + 1, end)
            if p >= end:
                return -1, MORE
            if buf[p] == 93:
                io[ERR_POS], io[ERR_CODE] = p, E_TRAILING_COMMA
                return -1, ERROR
        elif buf[p] == 93:
            p += 1
            break
        else:
            io[ERR_POS], io[ERR_CODE] = p, E_DELIM_ARRAY
            return -1, ERROR
    if matrix:
        if inner != 3 and kind == LIST_OK:
            kind = LIST_SHAPE
    return p, kind


@njit(cache=True, _nrt=False)
def _element_number(buf, p, end, io, data, elements, flags, st8, st64):
    """One number of a list of numbers: its text into `data`, its end offset into `elements`, 1 into `flags` for an
    integer literal (0 for a float literal). (end, kind) or (-1, status)."""
    b = buf[p]
    if b == 78 or b == 73:
        q, k = _word(buf, p, end, io)
    else:
        q, k, _ = _number(buf, p, end, io)
    if q < 0:
        return -1, k
    size = q - p
    if not (_room(st8, data, size, io, 0) and _room(st64, elements, 1, io, 1) and _room(st8, flags, 1, io, 0)):
        return -1, FULL
    _copy(st8, data, buf, p, size)
    _push(st64, elements, st8[3][data])
    st8[0][st8[1][flags] + st8[3][flags]] = 1 if k != FLOAT else 0
    st8[3][flags] += 1
    return q, k


@njit(cache=True, nogil=True, _nrt=False)
def scan(buf, end, final, io, spec, names, st8, st64, rec, kinds, records_start, layout_of, layouts, layout_counts,
         by_hash, dup, work, stack, seen):
    """Scan records from io[POS] to `end` (see the module's docstring). `final`: the window ends at the end of
    the file. Per record r: kinds[r, f], records_start[r] (file offset of the record), layout_of[r] (its key order
    as a row of `layouts`, whose first column counts the keys), dup[r] (field of a repeated key + 1, else 0)."""
    p = io[POS]
    r = io[RECORDS]
    state = io[STATE]
    nf = spec.shape[0]
    limit = io[MAX_STRING]
    n8, n64 = st8[3], st64[3]
    # work: the stream counts at the record's start (to undo it), then the record's key order
    saved8 = work[:len(n8)]
    saved64 = work[len(n8):len(n8) + len(n64)]
    order = work[len(n8) + len(n64):]
    hint = -1
    while True:
        p = _skip_ws(buf, p, end)
        if p >= end:
            io[POS], io[RECORDS], io[STATE] = p, r, state
            if final and state != S_END:
                io[ERR_POS], io[ERR_CODE] = p, E_EOF
                io[STATUS] = ERROR
            else:
                io[STATUS] = DONE if final else MORE
            return
        b = buf[p]
        if state == S_END:
            io[ERR_POS], io[ERR_CODE] = p, E_EXTRA_DATA
            io[STATUS] = ERROR
            return
        if state == S_AFTER:
            if b == 44:
                state = S_NEXT
                p += 1
                continue
            if b == 93:
                state = S_END
                p += 1
                continue
            io[ERR_POS], io[ERR_CODE] = p, E_DELIM_ARRAY
            io[STATUS] = ERROR
            return
        if b == 93:
            if state == S_NEXT:
                io[ERR_POS], io[ERR_CODE] = p, E_TRAILING_COMMA
                io[STATUS] = ERROR
                return
            state = S_END
            p += 1
            continue
        # a record starts at p
        if r >= kinds.shape[0]:
            io[POS], io[RECORDS], io[STATE], io[STATUS], io[ARG0] = p, r, state, FULL, -1
            return
        start = p
        for i in range(len(n8)):  # loops, not slice assignments: those allocate a copy each time
            saved8[i] = n8[i]
        for i in range(len(n64)):
            saved64[i] = n64[i]
        records_start[r] = io[FILE_OFFSET] + p
        dup[r] = 0
        for f in range(nf):
            kinds[r, f] = ABSENT
        status = DONE
        if b != 123:  # not an object: classified in layout_of (negated kind), checked, skipped
            q, k = _skip(buf, p, end, io, stack)
            if q < 0:
                status = k
            else:
                layout_of[r] = -1 - k
                p = q
        else:
            p = _skip_ws(buf, p + 1, end)
            nkeys = 0
            for f in range(nf):
                seen[f] = False
            guess = 0
            if p < end and buf[p] == 125:
                p += 1
            else:
                while True:
                    if p >= end:
                        status = MORE
                        break
                    if buf[p] != 34:
                        io[ERR_POS], io[ERR_CODE] = p, E_KEY
                        status = ERROR
                        break
                    key_start = p + 1
                    q = key_start
                    while q < end and buf[q] != 34 and buf[q] != 92 and 32 <= buf[q] < 128:
                        q += 1
                    if q >= end:
                        status = MORE
                        break
                    if buf[q] != 34:  # escapes, control characters or UTF-8: checked in full (the caller decodes)
                        q2, st = _string(buf, key_start, end, buf, 0, -1, 0, io)
                        if q2 < 0:
                            status = st
                            break
                        q = q2 - 1
                    key_end = q
                    f = -1
                    klen = key_end - key_start
                    n_names = names.shape[0]
                    for t in range(n_names):
                        g = (guess + t) % n_names
                        if names[g, 1] != klen:
                            continue
                        same = True
                        for k in range(klen):
                            if buf[key_start + k] != names[g, 2 + k]:
                                same = False
                                break
                        if same:
                            f = names[g, 0]
                            guess = g + 1
                            break
                    if f < 0:
                        io[ARG0], io[ARG1] = io[FILE_OFFSET] + key_start, io[FILE_OFFSET] + key_end
                        status = NEW_KEY
                        break
                    p = _skip_ws(buf, key_end + 1, end)
                    if p >= end:
                        status = MORE
                        break
                    if buf[p] != 58:
                        io[ERR_POS], io[ERR_CODE] = p, E_COLON
                        status = ERROR
                        break
                    p = _skip_ws(buf, p + 1, end)
                    if p >= end:
                        status = MORE
                        break
                    if seen[f]:  # a repeated key: noted, its value checked and skipped
                        if dup[r] == 0:
                            dup[r] = f + 1
                        q, k = _skip(buf, p, end, io, stack)
                        if q < 0:
                            status = k
                            break
                        p = q
                    else:
                        seen[f] = True
                        order[1 + nkeys] = f
                        nkeys += 1
                        q, k = _value(buf, p, end, io, f, r, spec, st8, st64, rec, limit, stack)
                        if q < 0:
                            status = k
                            break
                        kinds[r, f] = k
                        p = q
                    p = _skip_ws(buf, p, end)
                    if p >= end:
                        status = MORE
                        break
                    if buf[p] == 44:
                        p = _skip_ws(buf, p + 1, end)
                        if p < end and buf[p] == 125:
                            io[ERR_POS], io[ERR_CODE] = p, E_TRAILING_COMMA
                            status = ERROR
                            break
                        continue
                    if buf[p] == 125:
                        p += 1
                        break
                    io[ERR_POS], io[ERR_CODE] = p, E_DELIM_OBJECT
                    status = ERROR
                    break
            if status == DONE:
                order[0] = nkeys
                lid = _layout(order, nkeys, layouts, layout_counts, by_hash, io, hint)
                if lid < 0:
                    io[ERR_POS], io[ERR_CODE] = start, E_LAYOUTS
                    status = ERROR
                else:
                    layout_of[r] = lid
                    hint = lid
        if status == DONE:
            _close_record(r, spec, n8, n64, rec, kinds)
            r += 1
            state = S_AFTER
            continue
        # undo the record: the caller grows a stream, reads more, adds a key or reports the error
        for i in range(len(n8)):
            n8[i] = saved8[i]
        for i in range(len(n64)):
            n64[i] = saved64[i]
        if status == MORE and final:
            io[ERR_POS], io[ERR_CODE] = end, E_EOF
            status = ERROR
        io[POS], io[RECORDS], io[STATE], io[STATUS] = start, r, state, status
        if status == ERROR or status == NEW_KEY:
            io[POS] = start if status == NEW_KEY else io[POS]
        return


@njit(cache=True, _nrt=False)
def _layout(order, nkeys, layouts, counts, by_hash, io, hint):
    """The id of the key order `order[1:1+nkeys]` among the layouts seen so far (a new one is added); -1 past
    the table's capacity. `hint`: the layout to try first (the previous record's); `by_hash`: the first layout of
    each hash (a collision is searched in full)."""
    if 0 <= hint < io[LAYOUTS] and layouts[hint, 0] == nkeys:
        same = True
        for k in range(nkeys):
            if layouts[hint, 1 + k] != order[1 + k]:
                same = False
                break
        if same:
            counts[hint] += 1
            return hint
    h = np.int64(nkeys)
    for k in range(nkeys):
        h = h * np.int64(1000003) + order[1 + k] + 1
    first = _hash_get(by_hash, h)
    if first >= 0:
        for candidate in range(first, io[LAYOUTS]):
            same = layouts[candidate, 0] == nkeys
            if same:
                for k in range(nkeys):
                    if layouts[candidate, 1 + k] != order[1 + k]:
                        same = False
                        break
            if same:
                counts[candidate] += 1
                return candidate
    count = io[LAYOUTS]
    if count >= layouts.shape[0]:
        return -1
    for k in range(nkeys + 1):
        layouts[count, k] = order[k]
    if first < 0:
        _hash_put(by_hash, h, count)
    counts[count] = 1
    io[LAYOUTS] = count + 1
    return count


@njit(cache=True, _nrt=False)
def _hash_get(table, h):
    """The value of key h in the open-addressing table (rows: key, value + 1; 0 = empty), or -1."""
    size = table.shape[0]
    i = h & (size - 1)
    while table[i, 1] != 0:
        if table[i, 0] == h:
            return table[i, 1] - 1
        i = (i + 1) & (size - 1)
    return -1


@njit(cache=True, _nrt=False)
def _hash_put(table, h, value):
    size = table.shape[0]
    i = h & (size - 1)
    while table[i, 1] != 0:
        i = (i + 1) & (size - 1)
    table[i, 0], table[i, 1] = h, value + 1


@njit(cache=True, _nrt=False)
def _close_record(r, spec, n8, n64, rec, kinds):
    """Per-record offsets of every field (absent fields: an empty value)."""
    for f in range(spec.shape[0]):
        offsets = spec[f, OFFSETS]
        if offsets < 0:
            continue
        cls = spec[f, CLASS]
        if cls == C_STRING or cls == C_RAW or cls == C_INT:
            rec[r, offsets] = n8[spec[f, DATA]]
        else:  # lists: the end of the record's elements
            rec[r, offsets] = n64[spec[f, ELEMENTS]]
        if cls == C_INT and kinds[r, f] != INT:
            rec[r, spec[f, VALUES]] = 0


@njit(cache=True, _nrt=False)
def _value(buf, p, end, io, f, r, spec, st8, st64, rec, limit, stack):
    """The value of field f in record r at p: (end, kind) or (-1, status)."""
    cls = spec[f, CLASS]
    b = buf[p]
    if cls == C_STRING and b == 34:
        data = spec[f, DATA]
        base = st8[1][data]
        q, written = _string(buf, p + 1, end, st8[0], base + st8[3][data], base + st8[2][data], limit, io)
        if q < 0:
            return -1, _full(io, data, 0) if written == FULL else written
        if written > limit:
            return q, TOO_LONG
        st8[3][data] += written
        return q, STRING
    if cls == C_INT and (b == 45 or 48 <= b <= 57 or b == 78 or b == 73):
        if b == 78 or b == 73:
            q, k = _word(buf, p, end, io)
            v = 0
        else:
            q, k, v = _number(buf, p, end, io)
        if q < 0:
            return -1, k
        if k == INT:
            rec[r, spec[f, VALUES]] = v
        else:  # a float literal or an integer beyond int64: its text
            data = spec[f, DATA]
            if not _room(st8, data, q - p, io, 0):
                return -1, FULL
            _copy(st8, data, buf, p, q - p)
        return q, k
    if (cls == C_FLOATS or cls == C_MATRIX or cls == C_STRINGS) and b == 91:
        return _list(buf, p, end, io, f, spec, st8, st64, cls == C_MATRIX, cls == C_STRINGS, limit, stack)
    if cls == C_RAW:
        q, k = _skip(buf, p, end, io, stack)
        if q < 0:
            return -1, k
        data = spec[f, DATA]
        if q - p > limit:
            return q, TOO_LONG
        if not _room(st8, data, q - p, io, 0):
            return -1, FULL
        _copy(st8, data, buf, p, q - p)
        return q, k
    # a value of another JSON type than the field's: classified and skipped
    return _skip(buf, p, end, io, stack)
