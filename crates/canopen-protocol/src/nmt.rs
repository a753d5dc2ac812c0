//! NMT: module control commands (COB-ID 0x000) and the NMT states reported by
//! heartbeat / boot-up (COB-ID 0x700 + node), CiA 301 §7.2.8.3.

motus_wire::code_table! {
    /// NMT command specifier (byte 0 of a COB-ID 0x000 frame), CiA 301 §7.2.8.3.1.
    NmtCommand: u8 as "u8" {
        /// 0x01: start remote node (enter Operational).
        Start = 0x01 => "start",
        /// 0x02: stop remote node (enter Stopped).
        Stop = 0x02 => "stop",
        /// 0x80: enter Pre-operational.
        EnterPreOperational = 0x80 => "enter pre-operational",
        /// 0x81: reset node (application reset).
        ResetNode = 0x81 => "reset node",
        /// 0x82: reset communication.
        ResetCommunication = 0x82 => "reset communication",
    }
}

motus_wire::code_table! {
    /// NMT state byte of a heartbeat frame, CiA 301 §7.2.8.3.2.
    NmtState: u8 as "u8" {
        /// 0x00: boot-up (sent once after initialisation).
        BootUp = 0x00 => "boot-up",
        /// 0x04: Stopped.
        Stopped = 0x04 => "stopped",
        /// 0x05: Operational.
        Operational = 0x05 => "operational",
        /// 0x7F: Pre-operational.
        PreOperational = 0x7F => "pre-operational",
    }
}
