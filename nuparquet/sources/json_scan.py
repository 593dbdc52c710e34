"""The table reader's compiled kernel: one pass over a window of a JSON array of records that checks the grammar
as Python's json does and writes every field straight into typed column streams.

Longer than our ~300-line norm on purpose: it is one state machine (the grammar, strings, numbers, the records'
fields) that only makes sense read together; the Python side (`sources/tables.py`) does everything else.

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

_WS = np.zeros(256, np.bool_)
for _c in b" \t\n\r":
    _WS[_c] = True


@njit(cache=True, inline="always")
def _skip_ws(buf, p, end):
    while p < end and (buf[p] == 32 or buf[p] == 10 or buf[p] == 13 or buf[p] == 9):
        p += 1
    return p


@njit(cache=True)
def _hex(b):
    if 48 <= b <= 57:
        return b - 48
    if 97 <= b <= 102:
        return b - 87
    if 65 <= b <= 70:
        return b - 55
    return -1


@njit(cache=True)
def _u4(buf, p):
    v = 0
    for k in range(4):
        h = _hex(buf[p + k])
        if h < 0:
            return -1
        v = v * 16 + h
    return v


@njit(cache=True)
def _string(buf, p, end, out, o, cap, limit, io):
    """The string whose opening quote is at p-1, decoded into out[o:] (out None-like when cap < 0: check only).
    Returns (position after the closing quote, bytes written) or (-1, MORE/FULL/ERROR) with io set on ERROR.
    Over `limit` bytes the rest is checked but not written, and the length is returned negated."""
    n = 0
    copy = cap >= 0
    while True:
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


@njit(cache=True)
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


@njit(cache=True)
def _word(buf, p, end, io):
    """true/false/null/NaN/Infinity at p: (end, kind) or (-1, MORE/ERROR)."""
    b = buf[p]
    if b == 116:
        word, kind = "true", TRUE
    elif b == 102:
        word, kind = "false", FALSE
    elif b == 110:
        word, kind = "null", NULL
    elif b == 78:
        word, kind = "NaN", FLOAT
    else:
        word, kind = "Infinity", FLOAT
    n = len(word)
    for k in range(n):
        if p + k >= end:
            return -1, MORE
        if buf[p + k] != ord(word[k]):
            io[ERR_POS], io[ERR_CODE] = p, E_VALUE
            return -1, ERROR
    return p + n, kind


@njit(cache=True)
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


@njit(cache=True)
def _room(arrays, counts, sid, extra, io, which):
    """Whether stream `sid` has room for `extra` more items; if not, io names it (ARG0, ARG1: 0 bytes, 1 int64)."""
    if counts[sid] + extra <= arrays[sid].shape[0]:
        return True
    io[ARG0], io[ARG1] = sid, which
    return False


@njit(cache=True)
def _full(io, sid, which):
    io[ARG0], io[ARG1] = sid, which
    return FULL


@njit(cache=True)
def _list(buf, p, end, io, f, spec, u8, n8, i64, n64, matrix, strings, limit, stack):
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
                        r, k = _element_number(buf, q, end, io, data, elements, flags, u8, n8, i64, n64)
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
            r, k = _element_number(buf, p, end, io, data, elements, flags, u8, n8, i64, n64)
            if r < 0:
                return -1, k
            p = r
        elif strings and b == 34:
            q, written = _string(buf, p + 1, end, u8[data], n8[data], u8[data].shape[0], limit, io)
            if q < 0:
                return -1, _full(io, data, 0) if written == FULL else written
            if written > limit:
                kind = TOO_LONG
            else:
                n8[data] += written
            if not _room(i64, n64, elements, 1, io, 1):
                return -1, FULL
            i64[elements][n64[elements]] = n8[data]
            n64[elements] += 1
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


@njit(cache=True)
def _element_number(buf, p, end, io, data, elements, flags, u8, n8, i64, n64):
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
    if not (_room(u8, n8, data, size, io, 0) and _room(i64, n64, elements, 1, io, 1) and _room(u8, n8, flags, 1, io, 0)):
        return -1, FULL
    o = n8[data]
    for k2 in range(size):
        u8[data][o + k2] = buf[p + k2]
    n8[data] = o + size
    i64[elements][n64[elements]] = n8[data]
    n64[elements] += 1
    u8[flags][n8[flags]] = 1 if k != FLOAT else 0
    n8[flags] += 1
    return q, k


@njit(cache=True, nogil=True)
def scan(buf, end, final, io, spec, names, u8, n8, i64, n64, kinds, records_start, layout_of, layouts, layout_counts,
         by_hash, dup):
    """Scan records from io[POS] to `end` (see the module's docstring). `final`: the window ends at the end of
    the file. Per record r: kinds[r, f], records_start[r] (file offset of the record), layout_of[r] (its key order
    as a row of `layouts`, whose first column counts the keys), dup[r] (field of a repeated key + 1, else 0)."""
    p = io[POS]
    r = io[RECORDS]
    state = io[STATE]
    nf = spec.shape[0]
    limit = io[MAX_STRING]
    stack = np.empty(MAX_DEPTH, np.uint8)
    saved8 = n8.copy()
    saved64 = n64.copy()
    order = np.empty(nf + 1, np.int64)
    seen = np.zeros(nf, np.bool_)
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
        saved8[:] = n8
        saved64[:] = n64
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
                        q, k = _value(buf, p, end, io, f, r, spec, u8, n8, i64, n64, limit, stack)
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
                lid = _layout(order, nkeys, layouts, layout_counts, by_hash, io)
                if lid < 0:
                    io[ERR_POS], io[ERR_CODE] = start, E_LAYOUTS
                    status = ERROR
                else:
                    layout_of[r] = lid
        if status == DONE:
            _close_record(r, spec, n8, n64, i64, kinds)
            r += 1
            state = S_AFTER
            continue
        # undo the record: the caller grows a stream, reads more, adds a key or reports the error
        n8[:] = saved8
        n64[:] = saved64
        if status == MORE and final:
            io[ERR_POS], io[ERR_CODE] = end, E_EOF
            status = ERROR
        io[POS], io[RECORDS], io[STATE], io[STATUS] = start, r, state, status
        if status == ERROR or status == NEW_KEY:
            io[POS] = start if status == NEW_KEY else io[POS]
        return


@njit(cache=True)
def _layout(order, nkeys, layouts, counts, by_hash, io):
    """The id of the key order `order[1:1+nkeys]` among the layouts seen so far (a new one is added); -1 past
    the table's capacity. `by_hash`: the first layout of each hash (a collision is searched in full)."""
    h = np.int64(nkeys)
    for k in range(nkeys):
        h = h * np.int64(1000003) + order[1 + k] + 1
    first = by_hash.get(h, -1)
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
        by_hash[h] = count
    counts[count] = 1
    io[LAYOUTS] = count + 1
    return count


@njit(cache=True)
def _close_record(r, spec, n8, n64, i64, kinds):
    """Per-record offsets of every field (absent fields: an empty value)."""
    for f in range(spec.shape[0]):
        offsets = spec[f, OFFSETS]
        if offsets < 0:
            continue
        cls = spec[f, CLASS]
        if cls == C_STRING or cls == C_RAW or cls == C_INT:
            i64[offsets][r] = n8[spec[f, DATA]]
        else:  # lists: the end of the record's elements
            i64[offsets][r] = n64[spec[f, ELEMENTS]]
        if cls == C_INT and kinds[r, f] != INT:
            i64[spec[f, VALUES]][r] = 0


@njit(cache=True)
def _value(buf, p, end, io, f, r, spec, u8, n8, i64, n64, limit, stack):
    """The value of field f in record r at p: (end, kind) or (-1, status)."""
    cls = spec[f, CLASS]
    b = buf[p]
    if cls == C_STRING and b == 34:
        data = spec[f, DATA]
        q, written = _string(buf, p + 1, end, u8[data], n8[data], u8[data].shape[0], limit, io)
        if q < 0:
            return -1, _full(io, data, 0) if written == FULL else written
        if written > limit:
            return q, TOO_LONG
        n8[data] += written
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
            i64[spec[f, VALUES]][r] = v
        else:  # a float literal or an integer beyond int64: its text
            data = spec[f, DATA]
            if not _room(u8, n8, data, q - p, io, 0):
                return -1, FULL
            for k2 in range(q - p):
                u8[data][n8[data] + k2] = buf[p + k2]
            n8[data] += q - p
        return q, k
    if (cls == C_FLOATS or cls == C_MATRIX or cls == C_STRINGS) and b == 91:
        return _list(buf, p, end, io, f, spec, u8, n8, i64, n64, cls == C_MATRIX, cls == C_STRINGS, limit, stack)
    if cls == C_RAW:
        q, k = _skip(buf, p, end, io, stack)
        if q < 0:
            return -1, k
        data = spec[f, DATA]
        if q - p > limit:
            return q, TOO_LONG
        if not _room(u8, n8, data, q - p, io, 0):
            return -1, FULL
        for k2 in range(q - p):
            u8[data][n8[data] + k2] = buf[p + k2]
        n8[data] += q - p
        return q, k
    # a value of another JSON type than the field's: classified and skipped
    return _skip(buf, p, end, io, stack)
