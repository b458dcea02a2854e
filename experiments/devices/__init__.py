"""tactilab.experiments.devices: the displays and everything between a frame and the skin.

The display interface and its drive (:mod:`.display`), limits and strain (:mod:`.display_limits`,
:mod:`.display_strain`), the safety layer no stimulus can bypass (:mod:`.safety`), playback faults
(:mod:`.display_faults`), the simulated display, the UDP display with its paired link
(:mod:`.udp`, :mod:`.udp_link`, :mod:`.link`, :mod:`.pairing`), the loopback device emulator
(:mod:`.emulator`) and the registry of
device kinds (:mod:`.registry`: ``"simulated"``, ``"udp://HOST:PORT"``, plug-ins in the
``tactilab.devices`` entry-point group).

Door rule: this package is the room's one door. Code outside the room imports it from here,
never from the modules inside, and this room imports no other room of
:mod:`tactilab.experiments` (it knows nothing of procedures, sessions or models). The rooms
import one way: ``devices`` and ``procedures`` <- ``session`` <- ``modelling``
(tests/test_experiments_rooms.py enforces both rules).
"""

from tactilab.core import attach

#: public name -> module of this room that defines it (loaded on first use)
_EXPORTS = {
    "DEFAULT_DEPTH_M": "display",
    "DEFAULT_YOUNG_MODULUS_PA": "display",
    "Display": "display",
    "DisplayError": "display",
    "PlaybackReport": "display",
    "description_differences": "display_record",
    "description_record": "display_record",
    "render_drive": "display",
    "virtual_height": "display",
    "DisplayFault": "display_faults",
    "MAX_UNACKED_FRACTION": "display_faults",
    "display_fault": "display_faults",
    "foreign_reason": "display_faults",
    "check_frame_rate": "display_limits",
    "check_frames": "display_limits",
    "limit_violations": "display_limits",
    "limits": "display_limits",
    "resolve_command": "display_limits",
    "row_strain": "display_strain",
    "sliding_surface_strain_amplitude": "display_strain",
    "strain_gain_line_load": "display_strain",
    "STOP_SIGNALS": "safety",
    "PlaybackInterrupted": "safety",
    "SafeDisplay": "safety",
    "limit_drive": "safety",
    "SimulatedDisplay": "simulated_display",
    "create_pairing_key": "pairing",
    "read_pairing_key": "pairing",
    "UdpDisplay": "udp",
    "parse_udp_url": "udp",
    # the display UDP frame format (docs/udp-frame-format.md)
    "ARM": "link",
    "FRAME": "link",
    "FrameFormatError": "link",
    "decode": "link",
    "encode": "link",
    "EmulatorSummary": "emulator",
    "emulate": "emulator",
    "MAX_SECONDS": "emulator",
    "read_record": "emulator",
    "DEVICE_PRESETS": "registry",
    "description_from_spec": "registry",
    "open_display": "registry",
    "register_device": "registry",
    "registered_devices": "registry",
}

__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = attach(__name__, _EXPORTS)
