"""A machine.I2C stand-in that allocates nothing, for allocation probes of I2C drivers.

It serves a register image (taken from a simulated part) and a FIFO byte stream that loops
(packets taken from the simulated part), so ``allocprobe`` measures the driver alone: the
register-file simulators allocate on every read. Each data-register read moves the
temperature by ``t_step`` within ``t_span`` steps so temperature-dependent paths recompute.
Runs in the MicroPython VM (and on CPython).
"""


class ReplayI2C:
    def __init__(self, image, stream, fifo_count, t_base=0, t_step=8, t_span=64):
        self.regs = bytearray(image)
        self.stream = bytearray(stream)
        self.pos = 0
        self.count = fifo_count
        self.t_base = t_base
        self.t_step = t_step
        self.t_span = t_span
        self.tick = 0

    def readfrom_mem_into(self, addr, reg, buf):
        n = len(buf)
        i = 0
        if reg == 0x74:  # FIFO_R_W: no auto-increment, the stream loops
            s = self.stream
            p = self.pos
            end = len(s)
            while i < n:
                buf[i] = s[p]
                p += 1
                if p == end:
                    p = 0
                i += 1
            self.pos = p
            return
        if reg == 0x72:  # FIFO_COUNT_H/L
            buf[0] = self.count >> 8
            if n > 1:
                buf[1] = self.count & 0xFF
            return
        r = self.regs
        if reg == 0x3B or reg == 0x41:
            self.tick += 1
            if self.tick == self.t_span:
                self.tick = 0
            t = (self.t_base + self.tick * self.t_step) & 0xFFFF
            r[0x41] = t >> 8
            r[0x42] = t & 0xFF
        while i < n:
            buf[i] = r[reg + i]
            i += 1

    def readfrom_mem(self, addr, reg, n):
        b = bytearray(n)
        self.readfrom_mem_into(addr, reg, b)
        return bytes(b)

    def writeto_mem(self, addr, reg, buf):
        i = 0
        n = len(buf)
        while i < n:
            self.regs[reg + i] = buf[i]
            i += 1


class FrameI2C(ReplayI2C):
    """ReplayI2C whose 14-byte data read (ACCEL_XOUT_H..GYRO_ZOUT_L) costs one C call.

    On a board, ``machine.I2C.readfrom_mem_into`` is C code; ReplayI2C's Python byte loop would
    count as driver time in a benchmark. Here each data read copies the next of a ring of
    register frames with ``io.BytesIO.readinto``: the image's data registers with TEMP_OUT set
    to ``temps[i]`` (raw codes), frame i on read i.
    """

    def __init__(self, image, stream, fifo_count, temps):
        import io

        super().__init__(image, stream, fifo_count, t_step=0)
        ring = bytearray()
        for t in temps:
            f = bytearray(self.regs[0x3B:0x49])
            f[6] = (t >> 8) & 0xFF
            f[7] = t & 0xFF
            ring += f
        self.frames = io.BytesIO(ring)

    def readfrom_mem_into(self, addr, reg, buf):
        if reg == 0x3B and len(buf) == 14:
            f = self.frames
            if f.readinto(buf) < 14:
                f.seek(0)
                f.readinto(buf)
            return
        ReplayI2C.readfrom_mem_into(self, addr, reg, buf)
