"""The estimate CSV rows: the compiled batch formatter writes exactly what %-formatting writes."""
from __future__ import annotations

import math
import random
import struct

import pytest

from ecu_daemon import estimate_csv
from ecu_daemon.estimate_csv import ROW_FORMAT, format_row, format_rows
from ecu_daemon.estimator.estimate import ESTIMATE_FIELDS, Estimate

_INTS = estimate_csv._BOOL_FIELDS | estimate_csv._INT_FIELDS  # the "%d" columns


def _float(rng: random.Random) -> float:
    """Any double: random bit patterns (every exponent, subnormals, NaNs with either sign), the
    specials, values at rounding ties of %.6f / %.9g, and ordinary estimate magnitudes."""
    pick = rng.random()
    if pick < 0.3:
        return struct.unpack("<d", rng.getrandbits(64).to_bytes(8, "little"))[0]
    if pick < 0.4:
        return rng.choice((0.0, -0.0, math.inf, -math.inf, math.nan, -math.nan, 1e16, 1e-5, 1e-4,
                           123456789.5, 0.0000005, 2.5e-7, 1e300, -1e-300, 5e-324))
    if pick < 0.6:  # decimal ties and near-ties
        return rng.randint(-10 ** 9, 10 ** 9) / 10 ** rng.randint(0, 12) + rng.choice((0.0, 5e-7, 5e-10))
    return rng.uniform(-1e4, 1e4) * 10.0 ** rng.randint(-8, 8)


def _row(rng: random.Random) -> Estimate:
    vals = []
    for name in ESTIMATE_FIELDS:
        if name in _INTS:
            vals.append(rng.choice((True, False, 0, 7, 2 ** 40, -3, rng.getrandbits(62), -rng.getrandbits(63),
                                    rng.randint(-10 ** 6, 10 ** 6), 10 ** rng.randint(0, 18),
                                    -10 ** rng.randint(0, 18), 2 ** 63 - 1, -2 ** 63)))
        elif name == "t":
            vals.append(rng.choice((rng.uniform(0, 1e6), rng.uniform(-1e9, 1e9), 0.0, -0.0, math.nan,
                                    math.inf, -math.inf, 2.5e-7, 0.0000005, 1e15 + 0.5)))
        else:
            vals.append(_float(rng) if rng.random() < 0.9 else rng.randint(-5, 5))  # an int where a float goes
    return Estimate(*vals)


def test_format_rows_writes_what_percent_formatting_writes():
    if estimate_csv._format_rows_compiled is None:
        pytest.skip("the compiled CSV formatter is not built (pip install builds it)")
    rng = random.Random(3)
    rows = [_row(rng) for _ in range(4000)]
    expect = "".join(ROW_FORMAT % tuple(r) for r in rows)
    got = estimate_csv._format_rows_compiled(estimate_csv._KINDS, rows)
    assert got is not NotImplemented
    if got != expect:  # name the first differing field
        for r in rows:
            a = estimate_csv._format_rows_compiled(estimate_csv._KINDS, [r])
            assert a == format_row(r), r
    assert got == expect
    assert format_rows(rows[:10]) == expect[:sum(len(format_row(r)) for r in rows[:10])]


def test_what_the_compiled_formatter_does_not_take_is_formatted_by_python():
    """A "%d" field holding a float, an int wider than 64 bits, a "%.6f" too long for its room, a
    row of the wrong length: the
    compiled formatter declines and format_rows gives %-formatting's text (or its error)."""
    base = Estimate(*[0.5 if n not in _INTS else 1 for n in ESTIMATE_FIELDS])
    for row in (base._replace(status=3.7), base._replace(gnss_fused=2 ** 70), base._replace(t=1e300)):
        if estimate_csv._format_rows_compiled is not None:
            assert estimate_csv._format_rows_compiled(estimate_csv._KINDS, [row]) is NotImplemented
        assert format_rows([base, row]) == format_row(base) + format_row(row)
    if estimate_csv._format_rows_compiled is not None:
        assert estimate_csv._format_rows_compiled(estimate_csv._KINDS, [(1.0, 2.0)]) is NotImplemented


def test_repeated_column_values_reuse_their_text_only_for_the_same_bits():
    """The formatter reuses a column's text when its bits repeat the row before: rows that
    repeat, almost repeat (one ulp, -0.0 after 0.0, NaNs of other sign or payload, an int
    after the equal float) and repeat after a different row."""
    if estimate_csv._format_rows_compiled is None:
        pytest.skip("the compiled CSV formatter is not built (pip install builds it)")
    rng = random.Random(7)
    nan2 = struct.unpack("<d", struct.pack("<Q", 0x7FF8000000000001))[0]
    twins = [(0.0, -0.0), (math.nan, -math.nan), (math.nan, nan2), (1.0, math.nextafter(1.0, 2.0)),
             (0.1, 0.1), (math.inf, -math.inf), (5.0, 5), (2.5e-7, 2.5e-7)]
    rows = []
    for _ in range(600):
        a, b = rng.choice(twins)
        cols = [n for n in ESTIMATE_FIELDS if n not in _INTS and rng.random() < 0.7]
        r = _row(rng)._replace(**dict.fromkeys(cols, a))
        pick = rng.random()
        rows.append(r)
        rows.append(r._replace(**dict.fromkeys(cols, b if pick < 0.5 else a)))
        if pick > 0.8:
            rows.append(r)  # the same row again after another
    got = estimate_csv._format_rows_compiled(estimate_csv._KINDS, rows)
    assert got == "".join(ROW_FORMAT % tuple(r) for r in rows)


def _near_ties(rng: random.Random) -> float:
    """Values where a shortcut in the digits would show: decimal ties and their neighbours at 9
    significant digits and at 6 decimals, carries into a new digit (999999999.5), the switches
    between fixed and exponent layout, step times (k * 0.006), subnormals, 2**52 and beyond."""
    pick = rng.random()
    if pick < 0.3:
        v = rng.randint(-10 ** 10, 10 ** 10) / 10 ** rng.randint(0, 16)
        v = rng.choice((v, math.nextafter(v, math.inf), math.nextafter(v, -math.inf)))
    elif pick < 0.45:
        v = (rng.randint(0, 10 ** 9) + 0.5) * 10.0 ** rng.randint(-20, 5)
    elif pick < 0.6:
        v = rng.randint(0, 10 ** 7) * 0.006
    elif pick < 0.8:
        v = rng.uniform(-1, 1) * 10.0 ** rng.randint(-13, 12)
    else:
        v = rng.choice((0.0, 1e9, 999999999.5, 999999999.4999999, 9999999995.0, 1e-5, 1e-4, 9.9999999995e-5,
                        9.99999999e-5, 2.0 ** 52, 2.0 ** 52 - 1, 2.0 ** 53, 1e-11, 1e-12, 5e-324,
                        2.2250738585072014e-308, 5e-7, 1.5e-6, 2.5e-6, 1e16, 123456789.0, 1234567890.0,
                        0.1, 1 / 3, 100.0, 1e100, 1e-100, 0.0000005, 0.0000015))
    return v if rng.random() < 0.5 else -v


@pytest.mark.parametrize("kind,fmt", [(b"\x02", "%.9g"), (b"\x00", "%.6f")])
def test_float_digits_are_percent_formattings_at_ties_and_layout_switches(kind, fmt):
    """One float column at a time (so no text is reused from the row before): the compiled
    digits (exact 128-bit rounding, ties left to Python) give %-formatting's text."""
    if estimate_csv._format_rows_compiled is None:
        pytest.skip("the compiled CSV formatter is not built (pip install builds it)")
    rng = random.Random(11)
    xs = [_near_ties(rng) for _ in range(40000)]
    xs = [x for x in xs if len(fmt % x) < 60]  # %.6f of a huge value: Python's (the other test)
    got = estimate_csv._format_rows_compiled(kind, [(x,) for x in xs])
    if got != "".join(fmt % x + "\n" for x in xs):
        for x in xs:
            assert estimate_csv._format_rows_compiled(kind, [(x,)]) == fmt % x + "\n", repr(x)
    assert got == "".join(fmt % x + "\n" for x in xs)
