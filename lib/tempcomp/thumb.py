"""asm_thumb batch kernel of fixedpoint's 3-axis int16 burst path (ARM Cortex-M only).

``native`` imports it where the interpreter has the asm_thumb emitter; elsewhere the import
fails and the viper kernel is used. Same arithmetic as fixedpoint's pure path and native's
viper kernel (bound in native's docstring: every intermediate < 2**30, so 32-bit registers never
wrap). Only Thumb-1 instructions, so it also runs on Cortex-M0+ (the RP2040).

One call does the argument checks and the loop. An inline-assembler function sees a list as its
item array and a bytearray as its bytes, without their lengths, so the caller hands it a list
``[buf, out, p, type words]``: the objects themselves. The kernel checks each (a heap object of an accepted
type: bytes, bytearray or a memoryview of bytes in, a list or an int32 array out; the lengths; n
and stride in range)
and returns 1 without writing anything when one does not fit, so the caller takes its checked
path (a clear error, or the viper kernel for other buffer types). It writes each result straight
into a list's item array as a MicroPython small int (value << 1 | 1), or into an int32 array as
a plain word: no call per item.

The object layouts it reads (type word at +0, length at +8, items at +12: mp_obj_list_t,
mp_obj_array_t, mp_obj_str_t on 32-bit MicroPython) are checked by ``checked`` on live objects,
and the kernel is kept only after it reproduced the viper kernel on them, so a port with another
object representation falls back.
"""

# ruff: noqa: F821
# pyright: reportUndefinedVariable=false, reportIndexIssue=false, reportArgumentType=false, reportCallIssue=false
# (r0..r7, label, ldr and the other instructions are asm_thumb built-ins)

import array

import micropython

# Parameter words (array 'i'): g l c per axis at 0/12/24 (c: offset term minus half), k at 36,
# s at 40. Type words (array 'i'): list, bytearray, bytes, array.array, memoryview.


@micropython.asm_thumb
def _heads(r0, r1, r2):
    # r0: items of a list of objects, r1: 2 * r2 words: each object's word 0 (its type) and
    # word 2 (its length)
    label(NEXT)
    ldr(r3, [r0, 0])
    ldr(r4, [r3, 0])
    str(r4, [r1, 0])
    ldr(r4, [r3, 8])
    str(r4, [r1, 4])
    add(r0, 4)
    add(r1, 8)
    sub(r2, 1)
    bne(NEXT)


@micropython.asm_thumb
def batch(r0, r1, r2):
    # r0: items of [buf, out, p, the type words]; r1: n; r2: stride. Returns 0 when the n samples are written,
    # 1 when a check fails (nothing written).
    # 1 <= n < 2**15, 6 <= stride < 2**14: (n - 1) * stride + 6 < 2**29
    cmp(r1, 1)
    blt(FAIL)
    mov(r3, 1)
    lsl(r3, r3, 15)
    cmp(r1, r3)
    bge(FAIL)
    cmp(r2, 6)
    blt(FAIL)
    lsr(r3, r3, 1)
    cmp(r2, r3)
    bge(FAIL)
    ldr(r3, [r0, 12])
    ldr(r3, [r3, 12])  # the type words
    ldr(r4, [r0, 8])
    ldr(r4, [r4, 12])  # p's words
    ldr(r4, [r4, 36])
    cmp(r4, 15)  # k: 15 for every int16 burst (fixedpoint: K = 15 where the raw middle is 0)
    bne(FAIL)
    # buf: a bytearray, bytes or memoryview of bytes, (n - 1) * stride + 6 bytes or more
    ldr(r4, [r0, 0])
    lsl(r5, r4, 30)
    bne(FAIL)  # an immediate object (small int, qstr...), not a pointer
    sub(r6, r1, 1)
    mul(r6, r2)
    add(r6, 6)
    ldr(r5, [r4, 8])
    cmp(r5, r6)
    blt(FAIL)
    ldr(r5, [r4, 0])
    ldr(r6, [r3, 4])
    cmp(r5, r6)
    beq(BUF)
    ldr(r6, [r3, 8])
    cmp(r5, r6)
    beq(BUF)
    ldr(r6, [r3, 16])
    cmp(r5, r6)
    bne(FAIL)
    # a memoryview: its typecode (without the writable flag) one of a byte's: 1 (a bytearray's),
    # 'B', 'b'; its first byte `free` bytes into its items
    ldrb(r5, [r4, 4])
    lsl(r5, r5, 25)
    lsr(r5, r5, 25)
    cmp(r5, 1)
    beq(VIEW)
    cmp(r5, 0x42)
    beq(VIEW)
    cmp(r5, 0x62)
    bne(FAIL)
    label(VIEW)
    ldr(r5, [r4, 4])
    lsr(r5, r5, 8)
    ldr(r4, [r4, 12])
    add(r4, r4, r5)
    b(BYTES)
    label(BUF)
    ldr(r4, [r4, 12])  # the bytes
    label(BYTES)
    # out: a list (r7 = 1: small-int objects) or an int32 array (r7 = 0), 3 * n items or more
    ldr(r5, [r0, 4])
    lsl(r6, r5, 30)
    bne(FAIL)
    ldr(r6, [r5, 0])
    ldr(r7, [r3, 0])
    cmp(r6, r7)
    bne(ARR)
    mov(r7, 1)
    b(OUT)
    label(ARR)
    ldr(r7, [r3, 12])
    cmp(r6, r7)
    bne(FAIL)
    ldrb(r6, [r5, 4])  # the array's typecode
    cmp(r6, 0x69)  # 'i'
    beq(I32)
    cmp(r6, 0x6C)  # 'l': 32 bits on these ports
    bne(FAIL)
    label(I32)
    mov(r7, 0)
    label(OUT)
    add(r6, r1, r1)
    add(r6, r6, r1)
    ldr(r3, [r5, 8])
    cmp(r3, r6)
    blt(FAIL)
    ldr(r3, [r0, 8])
    ldr(r0, [r3, 12])  # p's words
    # For a list, (x >> (s - 1)) | 1 is (x >> s) << 1 | 1, the small int of x >> s: one shift
    # by s - r7 and an OR with r7 serve both kinds. r12: that shift, lr: the stride
    ldr(r6, [r0, 40])
    sub(r6, r6, r7)
    mov(r12, r6)
    mov(lr, r2)
    ldr(r2, [r5, 12])  # the out items
    mov(r3, r1)
    mov(r1, r4)
    b(LOOP)
    label(FAIL)  # here, within a conditional branch's reach of every check
    mov(r0, 1)
    b(END)
    label(LOOP)
    # axis 0: v = the sign-extended big-endian word; (v * g + ((v * l) >> 15) - c) >> s
    ldrb(r4, [r1, 0])
    lsl(r4, r4, 24)
    asr(r4, r4, 16)
    ldrb(r5, [r1, 1])
    orr(r4, r5)
    ldr(r5, [r0, 4])
    mul(r5, r4)
    asr(r5, r5, 15)
    ldr(r6, [r0, 0])
    mul(r6, r4)
    add(r5, r5, r6)
    ldr(r6, [r0, 8])
    sub(r5, r5, r6)
    mov(r6, r12)
    asr(r5, r6)
    orr(r5, r7)
    str(r5, [r2, 0])
    # axis 1
    ldrb(r4, [r1, 2])
    lsl(r4, r4, 24)
    asr(r4, r4, 16)
    ldrb(r5, [r1, 3])
    orr(r4, r5)
    ldr(r5, [r0, 16])
    mul(r5, r4)
    asr(r5, r5, 15)
    ldr(r6, [r0, 12])
    mul(r6, r4)
    add(r5, r5, r6)
    ldr(r6, [r0, 20])
    sub(r5, r5, r6)
    mov(r6, r12)
    asr(r5, r6)
    orr(r5, r7)
    str(r5, [r2, 4])
    # axis 2
    ldrb(r4, [r1, 4])
    lsl(r4, r4, 24)
    asr(r4, r4, 16)
    ldrb(r5, [r1, 5])
    orr(r4, r5)
    ldr(r5, [r0, 28])
    mul(r5, r4)
    asr(r5, r5, 15)
    ldr(r6, [r0, 24])
    mul(r6, r4)
    add(r5, r5, r6)
    ldr(r6, [r0, 32])
    sub(r5, r5, r6)
    mov(r6, r12)
    asr(r5, r6)
    orr(r5, r7)
    str(r5, [r2, 8])
    # next sample
    mov(r6, lr)
    add(r1, r1, r6)
    add(r2, 12)
    sub(r3, 1)
    bne(LOOP)
    mov(r0, 0)
    label(END)


def checked(reference):
    """(batch, the type words it compares) if batch reproduces reference (the viper kernel,
    reference(p, buf, out, n, stride)) on live objects of each accepted kind and refuses the
    others without writing; else None. The caller passes batch [buf, out, p, type words]."""
    raw = b"\x80\x00\x7f\xff\x12\x34\xfe\xdc\x00\x01\xff\xff\x00\x00\x00\x00"
    ba = bytearray(raw)
    heads = array.array("i", [0] * 10)
    _heads([[1, 2, 3], bytearray(5), b"1234567", array.array("i", [0, 1]), memoryview(ba)[3:7]], heads, 5)
    if [heads[2 * i + 1] for i in range(5)] != [3, 5, 7, 2, 4]:
        return None  # the lengths are not where this kernel reads them
    words = array.array("i", [heads[2 * i] for i in range(5)])
    p = array.array("i", [5000, 12345, 7, -4000, 321, -999999, 1, 0, 123456789, 15, 6])
    want = [0] * 6
    reference(p, raw, want, 2, 8)
    ok = True
    for buf in (ba, raw, memoryview(ba), memoryview(raw), memoryview(b"\x01\x02" + raw)[2:]):
        got = [0] * 7
        arr = array.array("i", got)
        ok = ok and batch([buf, got, p, words], 2, 8) == 0 and batch([buf, arr, p, words], 2, 8) == 0
        ok = ok and got == want + [0] and list(arr) == want + [0]
    # refused, nothing written: a short buffer or out, a view of wider items, an int16 array, a
    # tuple, immediate objects
    kept = [9] * 6
    for buf, out in ((raw[:13], kept), (memoryview(ba)[:13], kept), (raw, kept[:5]),
                     (memoryview(array.array("h", [0] * 16)), kept), (raw, array.array("h", kept)),
                     (raw, tuple(kept)), (7, kept), (raw, 7)):
        ok = ok and batch([buf, out, p, words], 2, 8) == 1
    return (batch, words) if ok and kept == [9] * 6 else None
