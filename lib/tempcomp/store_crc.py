"""CRC-32 (the zlib polynomial, as ``binascii.crc32``) bit by bit, for a port built without
``binascii.crc32``: ``tempcomp.store_format`` imports it only there. It imports nothing."""


def crc32(data):
    """binascii.crc32(data) for a bytes-like data, in Python."""
    c = 0xFFFFFFFF
    for b in data:
        c ^= b
        for _ in range(8):
            c = (c >> 1) ^ 0xEDB88320 if c & 1 else c >> 1
    return c ^ 0xFFFFFFFF
