//! Code tables of `specs/powerlink.md` §4: NMT states (§4.4), NMT command IDs (§4.5), SoA
//! requested services (§4.2) and SDO command IDs (§3.6). All are total: unknown values are
//! kept raw in an `Unknown` variant. In JSON they are the raw numbers.

motus_wire::code_table! {
    /// NMT state byte (PRes, SoA, IdentResponse, StatusResponse). The wire carries only the low
    /// byte; the same value means CS_x or MS_x depending on the sender (§4.4).
    NmtState: u8 as "u8" {
        /// 0x00 GS_OFF.
        Off = 0x00 => "GS_OFF",
        /// 0x19 GS_INITIALISING.
        Initialising = 0x19 => "GS_INITIALISING",
        /// 0x29 GS_RESET_APPLICATION.
        ResetApplication = 0x29 => "GS_RESET_APPLICATION",
        /// 0x39 GS_RESET_COMMUNICATION.
        ResetCommunication = 0x39 => "GS_RESET_COMMUNICATION",
        /// 0x79 GS_RESET_CONFIGURATION.
        ResetConfiguration = 0x79 => "GS_RESET_CONFIGURATION",
        /// 0x1C CS/MS_NOT_ACTIVE.
        NotActive = 0x1C => "NOT_ACTIVE",
        /// 0x1D CS/MS_PRE_OPERATIONAL_1.
        PreOperational1 = 0x1D => "PRE_OPERATIONAL_1",
        /// 0x5D CS/MS_PRE_OPERATIONAL_2.
        PreOperational2 = 0x5D => "PRE_OPERATIONAL_2",
        /// 0x6D CS/MS_READY_TO_OPERATE.
        ReadyToOperate = 0x6D => "READY_TO_OPERATE",
        /// 0xFD CS/MS_OPERATIONAL.
        Operational = 0xFD => "OPERATIONAL",
        /// 0x4D CS_STOPPED (CN only).
        Stopped = 0x4D => "STOPPED",
        /// 0x1E CS/MS_BASIC_ETHERNET.
        BasicEthernet = 0x1E => "BASIC_ETHERNET",
    }
}

motus_wire::code_table! {
    /// NMT command ID (ASnd NMTCommand byte 18, NMTRequest requested command) (§4.5).
    NmtCommandId: u8 as "u8" {
        /// 0x01 (NMTRequest only): please send an IdentResponse.
        IdentResponseRequest = 0x01 => "NMTRequest IdentResponse",
        /// 0x02 (NMTRequest only): please send a StatusResponse.
        StatusResponseRequest = 0x02 => "NMTRequest StatusResponse",
        /// 0x21 NMTStartNode.
        StartNode = 0x21 => "NMTStartNode",
        /// 0x22 NMTStopNode.
        StopNode = 0x22 => "NMTStopNode",
        /// 0x23 NMTEnterPreOperational2.
        EnterPreOperational2 = 0x23 => "NMTEnterPreOperational2",
        /// 0x24 NMTEnableReadyToOperate.
        EnableReadyToOperate = 0x24 => "NMTEnableReadyToOperate",
        /// 0x28 NMTResetNode.
        ResetNode = 0x28 => "NMTResetNode",
        /// 0x29 NMTResetCommunication.
        ResetCommunication = 0x29 => "NMTResetCommunication",
        /// 0x2A NMTResetConfiguration.
        ResetConfiguration = 0x2A => "NMTResetConfiguration",
        /// 0x2B NMTSwReset.
        SwReset = 0x2B => "NMTSwReset",
        /// 0x2C NMTGoToStandby (redundant MN).
        GoToStandby = 0x2C => "NMTGoToStandby",
        /// 0x2D DNA (wireshark).
        Dna = 0x2D => "NMTDNA",
        /// 0x41 NMTStartNodeEx (node-list bitmap in the data).
        StartNodeEx = 0x41 => "NMTStartNodeEx",
        /// 0x42 NMTStopNodeEx.
        StopNodeEx = 0x42 => "NMTStopNodeEx",
        /// 0x43 NMTEnterPreOperational2Ex.
        EnterPreOperational2Ex = 0x43 => "NMTEnterPreOperational2Ex",
        /// 0x44 NMTEnableReadyToOperateEx.
        EnableReadyToOperateEx = 0x44 => "NMTEnableReadyToOperateEx",
        /// 0x48 NMTResetNodeEx.
        ResetNodeEx = 0x48 => "NMTResetNodeEx",
        /// 0x49 NMTResetCommunicationEx.
        ResetCommunicationEx = 0x49 => "NMTResetCommunicationEx",
        /// 0x4A NMTResetConfigurationEx.
        ResetConfigurationEx = 0x4A => "NMTResetConfigurationEx",
        /// 0x4B NMTSwResetEx.
        SwResetEx = 0x4B => "NMTSwResetEx",
        /// 0x62 NMTNetHostNameSet.
        NetHostNameSet = 0x62 => "NMTNetHostNameSet",
        /// 0x63 NMTFlushArpEntry.
        FlushArpEntry = 0x63 => "NMTFlushArpEntry",
        /// 0x80 NMTPublishConfiguredNodes.
        PublishConfiguredNodes = 0x80 => "NMTPublishConfiguredNodes",
        /// 0x90 NMTPublishActiveNodes.
        PublishActiveNodes = 0x90 => "NMTPublishActiveNodes",
        /// 0x91 NMTPublishPreOperational1.
        PublishPreOperational1 = 0x91 => "NMTPublishPreOperational1",
        /// 0x92 NMTPublishPreOperational2.
        PublishPreOperational2 = 0x92 => "NMTPublishPreOperational2",
        /// 0x93 NMTPublishReadyToOperate.
        PublishReadyToOperate = 0x93 => "NMTPublishReadyToOperate",
        /// 0x94 NMTPublishOperational.
        PublishOperational = 0x94 => "NMTPublishOperational",
        /// 0x95 NMTPublishStopped.
        PublishStopped = 0x95 => "NMTPublishStopped",
        /// 0x96 NMTPublishNodeStates.
        PublishNodeStates = 0x96 => "NMTPublishNodeStates",
        /// 0xA0 NMTPublishEmergencyNew.
        PublishEmergencyNew = 0xA0 => "NMTPublishEmergencyNew",
        /// 0xB0 NMTPublishTime.
        PublishTime = 0xB0 => "NMTPublishTime",
        /// 0xFF NMTInvalidService.
        InvalidService = 0xFF => "NMTInvalidService",
    }
}

motus_wire::code_table! {
    /// SoA RequestedServiceID (§4.2). 0xA0..=0xFE are manufacturer-specific and decode as
    /// `Unknown` (see [`RequestedService::is_manufacturer_specific`]).
    RequestedService: u8 as "u8" {
        /// 0x00: nobody may send.
        NoService = 0x00 => "NoService",
        /// 0x01: IdentRequest.
        IdentRequest = 0x01 => "IdentRequest",
        /// 0x02: StatusRequest.
        StatusRequest = 0x02 => "StatusRequest",
        /// 0x03: NMTRequestInvite.
        NmtRequestInvite = 0x03 => "NMTRequestInvite",
        /// 0x06: SyncRequest (PRes chaining).
        SyncRequest = 0x06 => "SyncRequest",
        /// 0xFF: UnspecifiedInvite (generic async: SDO, IP...).
        UnspecifiedInvite = 0xFF => "UnspecifiedInvite",
    }
}

impl RequestedService {
    /// True for the manufacturer-specific range 0xA0..=0xFE.
    pub fn is_manufacturer_specific(self) -> bool {
        (0xA0..=0xFE).contains(&self.raw())
    }
}

motus_wire::code_table! {
    /// SDO command-layer command ID (§3.6, ASnd service 5, frame byte 25).
    SdoCommandId: u8 as "u8" {
        /// 0x00: no command (sequence-layer-only frames).
        Nil = 0x00 => "NIL",
        /// 0x01 WriteByIndex.
        WriteByIndex = 0x01 => "WriteByIndex",
        /// 0x02 ReadByIndex.
        ReadByIndex = 0x02 => "ReadByIndex",
        /// 0x03 WriteAllByIndex.
        WriteAllByIndex = 0x03 => "WriteAllByIndex",
        /// 0x04 ReadAllByIndex.
        ReadAllByIndex = 0x04 => "ReadAllByIndex",
        /// 0x05 WriteByName.
        WriteByName = 0x05 => "WriteByName",
        /// 0x06 ReadByName.
        ReadByName = 0x06 => "ReadByName",
        /// 0x20 FileWrite.
        FileWrite = 0x20 => "FileWrite",
        /// 0x21 FileRead.
        FileRead = 0x21 => "FileRead",
        /// 0x31 WriteMultipleParamByIndex.
        WriteMultipleParamByIndex = 0x31 => "WriteMultipleParamByIndex",
        /// 0x32 ReadMultipleParamByIndex.
        ReadMultipleParamByIndex = 0x32 => "ReadMultipleParamByIndex",
        /// 0x70 MaxSegmentSize.
        MaxSegmentSize = 0x70 => "MaxSegmentSize",
    }
}
