"""asm_thumb batch kernel of fixedpoint's 3-axis int16 burst path (ARM Cortex-M only).

``native`` imports it where the interpreter has the asm_thumb emitter; elsewhere the import
fails and the viper kernel is used. Same arithmetic as fixedpoint's pure path and native's
viper kernel (bound in native's docstring: every intermediate < 2**30, so 32-bit registers never
wrap). Only Thumb-1 instructions, so it also runs on Cortex-M0.

It writes each result straight into a list's item array as a MicroPython small int
(value << 1 | 1), or into an int32 array as a plain word: no call per item. ``checked`` keeps it only after it reproduced the viper
kernel on a known sample, so a port with another object representation falls back.
"""

# ruff: noqa: F821
# pyright: reportUndefinedVariable=false, reportIndexIssue=false, reportArgumentType=false, reportCallIssue=false
# (r0..r7, label, ldr and the other instructions are asm_thumb built-ins)

import array

import micropython


@micropython.asm_thumb
def _many_list(r0, r1, r2, r3):
    # r0: parameter words (g l c per axis at 0/12/24, k at 36, s at 40)
    # r1: the bytes, r2: the list's items or the int32 array's words
    # r3: stride << 16 | tag << 15 | n (n >= 1 samples; tag 1 stores small-int objects
    # v << 1 | 1 into a list's items, 0 plain words into an int32 array); n counts down in place
    label(LOOP)
    # axis 0: v = sign-extended big-endian word
    ldrb(r4, [r1, 0])
    lsl(r4, r4, 24)
    asr(r4, r4, 16)
    ldrb(r5, [r1, 1])
    orr(r4, r5)
    ldr(r6, [r0, 4])
    mul(r6, r4)
    ldr(r5, [r0, 36])
    asr(r6, r5)
    ldr(r7, [r0, 0])
    mul(r7, r4)
    add(r6, r6, r7)
    ldr(r5, [r0, 8])
    sub(r6, r6, r5)
    ldr(r5, [r0, 40])
    asr(r6, r5)
    lsl(r5, r3, 16)
    lsr(r5, r5, 31)
    lsl(r6, r5)
    orr(r6, r5)
    str(r6, [r2, 0])
    # axis 1
    ldrb(r4, [r1, 2])
    lsl(r4, r4, 24)
    asr(r4, r4, 16)
    ldrb(r5, [r1, 3])
    orr(r4, r5)
    ldr(r6, [r0, 16])
    mul(r6, r4)
    ldr(r5, [r0, 36])
    asr(r6, r5)
    ldr(r7, [r0, 12])
    mul(r7, r4)
    add(r6, r6, r7)
    ldr(r5, [r0, 20])
    sub(r6, r6, r5)
    ldr(r5, [r0, 40])
    asr(r6, r5)
    lsl(r5, r3, 16)
    lsr(r5, r5, 31)
    lsl(r6, r5)
    orr(r6, r5)
    str(r6, [r2, 4])
    # axis 2
    ldrb(r4, [r1, 4])
    lsl(r4, r4, 24)
    asr(r4, r4, 16)
    ldrb(r5, [r1, 5])
    orr(r4, r5)
    ldr(r6, [r0, 28])
    mul(r6, r4)
    ldr(r5, [r0, 36])
    asr(r6, r5)
    ldr(r7, [r0, 24])
    mul(r7, r4)
    add(r6, r6, r7)
    ldr(r5, [r0, 32])
    sub(r6, r6, r5)
    ldr(r5, [r0, 40])
    asr(r6, r5)
    lsl(r5, r3, 16)
    lsr(r5, r5, 31)
    lsl(r6, r5)
    orr(r6, r5)
    str(r6, [r2, 8])
    # next sample
    lsr(r5, r3, 16)
    add(r1, r1, r5)
    add(r2, 12)
    sub(r3, 1)
    lsl(r4, r3, 17)
    bne(LOOP)


def checked(reference):
    """_many_list if it reproduces reference (the viper kernel) on a known sample, else None."""
    p = array.array("i", [5000, 12345, 7, -4000, 321, -999999, 1, 0, 123456789, 15, 6])
    buf = bytearray(b"\x80\x00\x7f\xff\x12\x34\xfe\xdc\x00\x01\xff\xff")
    want = [0] * 6
    reference(p, buf, want, 2, 6)
    got = [0] * 6
    _many_list(p, buf, got, 6 << 16 | 0x8000 | 2)
    arr = array.array("i", got)
    _many_list(p, buf, arr, 6 << 16 | 2)
    return _many_list if got == want and list(arr) == want else None
