"""Raw FMCW captures on disk: TI MMWCAS cascade, DCA1000 and OpenRadar ``.npy`` files.

Every reader returns complex64 cubes with axes ``(frames, chirps, tx, rx, samples)``: ``chirps``
counts chirp *loops*, ``tx`` is the chirp slot within a loop (the order the TX fired; the
physical TX of slot k is ``RadarConfig.tx_order[k]``) and ``rx`` is in file order. Integer ADC
codes are returned as they are (no scaling). Each format is one module, with its reader, writer
and its recording, a :class:`blindspot.radar.source.FrameSource` that reads lazily, one frame at
a time:

=======================  ====================================  ================================
module                   format                                frame source
=======================  ====================================  ================================
:mod:`.ti_cascade`       TI MMWCAS ``{master,slave1..3}_NNNN_  :class:`TICascadeRecording`
                         {data,idx}.bin``
:mod:`.dca1000`          DCA1000 ``adc_data.bin``              :class:`DCA1000Recording`
                         (xWR16xx/xWR14xx)
:mod:`.dca1000_packets`  DCA1000 packet-level record           :class:`DCA1000PacketRecording`
                         ``adc_data_Raw_N.bin``
:mod:`.openradar`        OpenRadar example ``.npy``            :class:`OpenRadarRecording`
=======================  ====================================  ================================

:mod:`.common` holds what they share (:class:`CaptureError`, int16 codes, size checks, writes
through :func:`blindspot.io.atomic_path`); :func:`open_recording` opens a recording by its kind.
Errors name the file, the size found and the size expected. A headerless file whose size is not a
whole number of frames is read with a warning listing the causes that fit its numbers (cut
capture, lost packets, wrong profile, zero padding), never as a proven cut end; ``strict=True``
(also through :func:`open_recording`) raises :class:`CaptureError` instead.
"""

from blindspot.radar.capture.common import CaptureError, Int16Conversion, to_int16_iq
from blindspot.radar.capture.dca1000 import (
    DCA1000_PAYLOAD_BYTES,
    ZERO_RUN_CODES,
    DCA1000Capture,
    DCA1000Recording,
    DcaDiagnosis,
    DcaLayout,
    FrameQuality,
    dca1000_frame_bytes,
    read_dca1000,
    write_dca1000,
)
from blindspot.radar.capture.dca1000_packets import (
    DCA1000PacketCapture,
    DCA1000PacketRecording,
    PacketReport,
    read_dca1000_packets,
    write_dca1000_packets,
)
from blindspot.radar.capture.openradar import OpenRadarRecording, read_openradar_npy
from blindspot.radar.capture.recording import RECORDING_KINDS, open_recording
from blindspot.radar.capture.ti_cascade import (
    CASCADE_DEVICES,
    CASCADE_N_RX,
    IDX_ENTRY_DTYPE,
    IDX_HEADER_DTYPE,
    CascadeIndex,
    CascadePart,
    TICascadeCapture,
    TICascadeRecording,
    cascade_frame_bytes,
    find_cascade_captures,
    find_cascade_parts,
    read_cascade_index,
    read_ti_cascade,
    write_ti_cascade,
)

__all__ = [
    "CaptureError",
    "Int16Conversion",
    "DcaLayout",
    "CASCADE_DEVICES",
    "CASCADE_N_RX",
    "IDX_HEADER_DTYPE",
    "IDX_ENTRY_DTYPE",
    "CascadeIndex",
    "CascadePart",
    "TICascadeCapture",
    "TICascadeRecording",
    "DCA1000_PAYLOAD_BYTES",
    "ZERO_RUN_CODES",
    "DCA1000Capture",
    "DCA1000Recording",
    "DcaDiagnosis",
    "FrameQuality",
    "DCA1000PacketCapture",
    "DCA1000PacketRecording",
    "PacketReport",
    "OpenRadarRecording",
    "RECORDING_KINDS",
    "cascade_frame_bytes",
    "dca1000_frame_bytes",
    "find_cascade_captures",
    "find_cascade_parts",
    "open_recording",
    "read_cascade_index",
    "read_ti_cascade",
    "write_ti_cascade",
    "read_dca1000",
    "write_dca1000",
    "read_dca1000_packets",
    "write_dca1000_packets",
    "read_openradar_npy",
    "to_int16_iq",
]
