"""A minimal ArduPilot DataFlash writer (pymavlink has a reader only): FMT messages, then ``0xA3 0x95 id payload``
messages packed as LogStructure.h lays them out (``libraries/AP_Logger/LogStructure.h``: the FMT message is
``BBnNZ`` = type, length, name[4], format[16], columns[64], its own id 128)."""

from __future__ import annotations

import struct
from pathlib import Path

HEAD = b"\xa3\x95"
FMT_ID = 128
#: pymavlink's struct characters of the format characters used here (DFReader.FORMAT_TO_STRUCT).
STRUCT = {"Q": "Q", "B": "B", "f": "f", "I": "I", "h": "h", "H": "H"}
#: Current firmware's messages (LogStructure.h): name → (id, format, columns).
IMU = (129, "QBffffffIIfBBHH", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH,GHz,AHz")
VIBE = (130, "QBfffI", "TimeUS,IMU,VibeX,VibeY,VibeZ,Clip")
MAG = (131, "QBhhhhhhhhhBI", "TimeUS,I,MagX,MagY,MagZ,OfsX,OfsY,OfsZ,MOX,MOY,MOZ,Health,S")
ACC = (132, "QBQfff", "TimeUS,I,SampleUS,AccX,AccY,AccZ")
GYR = (133, "QBQfff", "TimeUS,I,SampleUS,GyrX,GyrY,GyrZ")
MESSAGES = {"IMU": IMU, "VIBE": VIBE, "MAG": MAG, "ACC": ACC, "GYR": GYR}


class DataFlashWriter:
    """Collects messages and writes a ``.bin``: ``add("IMU", t_us, 0, gx, ...)``."""

    def __init__(self) -> None:
        self.out = bytearray()
        fmt_struct = struct.Struct("<BB4s16s64s")
        self.out += HEAD + bytes([FMT_ID]) + fmt_struct.pack(FMT_ID, 3 + fmt_struct.size, b"FMT", b"BBnNZ",
                                                            b"Type,Length,Name,Format,Columns")
        self.structs: dict[str, tuple[int, struct.Struct]] = {}
        for name, (mid, fmt, cols) in MESSAGES.items():
            st = struct.Struct("<" + "".join(STRUCT[c] for c in fmt))
            self.structs[name] = (mid, st)
            self.out += HEAD + bytes([FMT_ID]) + fmt_struct.pack(mid, 3 + st.size, name.encode(), fmt.encode(),
                                                                cols.encode())

    def add(self, name: str, *values: float) -> None:
        mid, st = self.structs[name]
        self.out += HEAD + bytes([mid]) + st.pack(*values)

    def write(self, path: Path) -> None:
        Path(path).write_bytes(bytes(self.out))
