//! SDO abort codes (CiA 301 §7.2.4.3.17, table 22). Total: unknown codes stay raw.

motus_wire::code_table! {
    /// SDO abort code (UNSIGNED32, bytes 4–7 of an abort frame), CiA 301 table 22.
    SdoAbortCode: u32 as "u32" {
        /// 0x05030000
        ToggleBitNotAlternated = 0x0503_0000 => "toggle bit not alternated",
        /// 0x05040000
        Timeout = 0x0504_0000 => "SDO protocol timed out",
        /// 0x05040001
        InvalidCommandSpecifier = 0x0504_0001 => "command specifier not valid or unknown",
        /// 0x05040002
        InvalidBlockSize = 0x0504_0002 => "invalid block size",
        /// 0x05040003
        InvalidSequenceNumber = 0x0504_0003 => "invalid sequence number",
        /// 0x05040004
        CrcError = 0x0504_0004 => "CRC error",
        /// 0x05040005
        OutOfMemory = 0x0504_0005 => "out of memory",
        /// 0x06010000
        UnsupportedAccess = 0x0601_0000 => "unsupported access to an object",
        /// 0x06010001
        WriteOnly = 0x0601_0001 => "attempt to read a write-only object",
        /// 0x06010002
        ReadOnly = 0x0601_0002 => "attempt to write a read-only object",
        /// 0x06020000
        ObjectDoesNotExist = 0x0602_0000 => "object does not exist in the object dictionary",
        /// 0x06040041
        NotMappable = 0x0604_0041 => "object cannot be mapped to the PDO",
        /// 0x06040042
        PdoLengthExceeded = 0x0604_0042 => "number and length of objects to be mapped would exceed PDO length",
        /// 0x06040043
        ParameterIncompatibility = 0x0604_0043 => "general parameter incompatibility",
        /// 0x06040047
        InternalIncompatibility = 0x0604_0047 => "general internal incompatibility in the device",
        /// 0x06060000
        HardwareError = 0x0606_0000 => "access failed due to a hardware error",
        /// 0x06070010
        TypeLengthMismatch = 0x0607_0010 => "data type does not match, length of service parameter does not match",
        /// 0x06070012
        TypeLengthTooHigh = 0x0607_0012 => "data type does not match, length of service parameter too high",
        /// 0x06070013
        TypeLengthTooLow = 0x0607_0013 => "data type does not match, length of service parameter too low",
        /// 0x06090011
        SubIndexDoesNotExist = 0x0609_0011 => "sub-index does not exist",
        /// 0x06090030
        InvalidValue = 0x0609_0030 => "invalid value for parameter",
        /// 0x06090031
        ValueTooHigh = 0x0609_0031 => "value of parameter written too high",
        /// 0x06090032
        ValueTooLow = 0x0609_0032 => "value of parameter written too low",
        /// 0x06090036
        MaxLessThanMin = 0x0609_0036 => "maximum value is less than minimum value",
        /// 0x060A0023
        ResourceNotAvailable = 0x060A_0023 => "resource not available: SDO connection",
        /// 0x08000000
        GeneralError = 0x0800_0000 => "general error",
        /// 0x08000020
        CannotTransfer = 0x0800_0020 => "data cannot be transferred or stored to the application",
        /// 0x08000021
        LocalControl = 0x0800_0021 => "data cannot be transferred or stored to the application because of local control",
        /// 0x08000022
        DeviceState = 0x0800_0022 => "data cannot be transferred or stored to the application because of the present device state",
        /// 0x08000023
        NoObjectDictionary = 0x0800_0023 => "object dictionary dynamic generation fails or no object dictionary is present",
        /// 0x08000024
        NoDataAvailable = 0x0800_0024 => "no data available",
    }
}
