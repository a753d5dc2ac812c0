//! The built-in dictionary of a Controlled Node: the communication profile (EPSG DS 301) and
//! the CiA 401 digital and analogue I/O, following openPOWERLINK V2.7.2's demo CN device
//! description `00000000_POWERLINK_CiA401_CN.xdd` (`shared/oracles/openpowerlink/xdd/`):
//! every object of that XDD with its name, type, access, PDO mappability, limits and default,
//! apart from the identity values ([`DeviceIdentity`]) and the deviations noted at
//! [`ObjectDictionary::controlled_node`].

use super::entry::{Access, Entry, Object, PdoMappable};
use super::ObjectDictionary;
use crate::codes::NmtState;

/// FeatureFlags bit 0: isochronous.
const FEATURE_ISOCHRONOUS: u32 = 1 << 0;
/// FeatureFlags bit 2: SDO by ASnd.
const FEATURE_SDO_ASND: u32 = 1 << 2;
/// FeatureFlags bit 5: extended NMT state commands.
const FEATURE_EXTENDED_NMT_COMMANDS: u32 = 1 << 5;
/// FeatureFlags bit 6: dynamic PDO mapping.
const FEATURE_DYNAMIC_PDO_MAPPING: u32 = 1 << 6;

/// The FeatureFlags (0x1F82) a Motus CN announces: isochronous, SDO by ASnd, extended NMT
/// commands, dynamic PDO mapping (0x0000_0065). The XDD's default is 0x0005_8265 and the
/// openPOWERLINK demo CN announces 0x0001_0265 (`oplk_mn_cn_bridge_monitor.pcapng`, frame 859):
/// both add multiplexed access, multiple ASnd and (XDD) SDO read/write multiple and PRes
/// chaining, which a Motus CN does not offer.
pub const MOTUS_CN_FEATURE_FLAGS: u32 =
    FEATURE_ISOCHRONOUS | FEATURE_SDO_ASND | FEATURE_EXTENDED_NMT_COMMANDS | FEATURE_DYNAMIC_PDO_MAPPING;

/// What identifies a device: the values of 0x1000, 0x1008-0x100A, 0x1018, 0x1030/5 and 0x1F82,
/// which the IdentResponse carries too.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeviceIdentity {
    /// NMT_DeviceType_U32 (0x1000): device profile (low 16 bits) and additional information.
    pub device_type: u32,
    /// VendorId_U32 (0x1018/1).
    pub vendor_id: u32,
    /// ProductCode_U32 (0x1018/2).
    pub product_code: u32,
    /// RevisionNo_U32 (0x1018/3).
    pub revision_number: u32,
    /// SerialNo_U32 (0x1018/4).
    pub serial_number: u32,
    /// NMT_ManufactDevName_VS (0x1008).
    pub device_name: String,
    /// NMT_ManufactHwVers_VS (0x1009).
    pub hardware_version: String,
    /// NMT_ManufactSwVers_VS (0x100A).
    pub software_version: String,
    /// InterfacePhysAddress_OSTR (0x1030/5): the interface's MAC address.
    pub mac_address: [u8; 6],
    /// NMT_FeatureFlags_U32 (0x1F82).
    pub feature_flags: u32,
}

impl Default for DeviceIdentity {
    /// The XDD's device type (0x000F0191: CiA 401, digital and analogue I/O), vendor and
    /// product 0, revision 0x00020007 and hardware version "1.00"; Motus's own name,
    /// software version and [`MOTUS_CN_FEATURE_FLAGS`]; MAC address and serial number 0.
    fn default() -> Self {
        DeviceIdentity {
            device_type: 0x000F_0191,
            vendor_id: 0,
            product_code: 0,
            revision_number: 0x0002_0007,
            serial_number: 0,
            device_name: "Motus POWERLINK CN".to_owned(),
            hardware_version: "1.00".to_owned(),
            software_version: concat!("Motus ", env!("CARGO_PKG_VERSION")).to_owned(),
            mac_address: [0; 6],
            feature_flags: MOTUS_CN_FEATURE_FLAGS,
        }
    }
}

/// Largest PReq/PRes payload the node handles (IsochrTxMaxPayload_U16, IsochrRxMaxPayload_U16).
const MAX_PAYLOAD: u16 = 1490;
/// Mapping entries per PDO mapping object in the XDD.
const MAPPING_ENTRIES: u8 = 25;

fn var(od: &mut ObjectDictionary, index: u16, entry: Entry) {
    od.insert(index, Object::var(entry));
}

/// An ARRAY whose subindex 0 the XDD makes writable (rw, default = highest subindex unless
/// given).
fn rw_array(od: &mut ObjectDictionary, index: u16, name: &'static str, count: u8, sub0: u8, element: Entry) {
    od.insert(index, Object::array(name, count, element).number_of_entries(Access::ReadWrite, sub0));
}

/// The error counter records 0x1C0B, 0x1C0D, 0x1C0F (DLL_ErrorCntRec_TYPE).
fn error_counter(name: &'static str) -> Object {
    Object::record(
        name,
        [
            Entry::unsigned32("CumulativeCnt_U32", Access::ReadWrite, 0),
            Entry::unsigned32("ThresholdCnt_U32", Access::ReadOnly, 0),
            Entry::unsigned32("Threshold_U32", Access::ReadWrite, 15),
        ],
    )
}

/// A PDO communication record 0x1400+n / 0x1800+n.
fn pdo_comm(name: &'static str) -> Object {
    Object::record(
        name,
        [
            Entry::unsigned8("NodeID_U8", Access::ReadWrite, 0).high_limit(254),
            Entry::unsigned8("MappingVersion_U8", Access::ReadWrite, 0),
        ],
    )
}

/// A PDO mapping array 0x1600+n / 0x1A00+n: 25 UNSIGNED64 entries, disabled.
fn pdo_mapping(od: &mut ObjectDictionary, index: u16, name: &'static str) {
    let entry = Entry::unsigned64("ObjectMapping", Access::ReadWrite, 0);
    rw_array(od, index, name, MAPPING_ENTRIES, 0, entry);
}

impl ObjectDictionary {
    /// The dictionary of a Controlled Node with node ID `node_id` (1-239; stored in 0x1F93/1,
    /// not checked), following openPOWERLINK's demo CN device description
    /// `00000000_POWERLINK_CiA401_CN.xdd`, so that the openPOWERLINK demo MN (`demo_3cn_*.cdc`)
    /// can boot and configure it:
    ///
    /// * communication profile: 0x1000, 0x1001, 0x1006, 0x1008-0x100A, 0x1018, 0x1020,
    ///   0x1030, 0x1050, 0x1300, RPDO 0x1400-0x1402 / 0x1600-0x1602, TPDO 0x1800 / 0x1A00
    ///   (25 entries each, disabled), 0x1C0B, 0x1C0D, 0x1C0F, 0x1C14, 0x1F81, 0x1F82, 0x1F83,
    ///   0x1F8C, 0x1F8D, 0x1F93, 0x1F98, 0x1F99, 0x1F9B, 0x1F9E;
    /// * CiA 401: 0x6000 digital inputs (4 x UNSIGNED8, TPDO: sent in PRes), 0x6200 digital
    ///   outputs (4 x UNSIGNED8, RPDO: received in PReq), 0x6400-0x6402 analogue inputs,
    ///   0x6410-0x6412 analogue outputs.
    ///
    /// Deviations from the XDD: the identity values come from `identity`; 0x1F98/3
    /// PResMaxLatency_U32 is 50 000 ns, what openPOWERLINK's CN announces as ResponseTime
    /// (frame 859 of `oplk_mn_cn_bridge_monitor.pcapng`), not the XDD's 2000 ns. 0x1F8C
    /// (current NMT state, no XDD default) starts at GS_INITIALISING; the runtime keeps it
    /// current with [`ObjectDictionary::set_u8`]. Like openPOWERLINK's CN it has no
    /// 0x1010/0x1011 (store/restore parameters): the MN's writes there are refused with
    /// "object does not exist", which the MN accepts.
    pub fn controlled_node(node_id: u8, identity: &DeviceIdentity) -> ObjectDictionary {
        let mut od = ObjectDictionary::new();
        build_controlled_node(&mut od, node_id, identity);
        od
    }
}

/// The table of [`ObjectDictionary::controlled_node`].
fn build_controlled_node(od: &mut ObjectDictionary, node_id: u8, id: &DeviceIdentity) {
    use Access::{Const, ReadOnly as Ro, ReadWrite as Rw};
    // Communication profile area (0x1000-0x1FFF).
    var(od, 0x1000, Entry::unsigned32("NMT_DeviceType_U32", Const, id.device_type));
    var(od, 0x1001, Entry::unsigned8("ERR_ErrorRegister_U8", Ro, 0).pdo(PdoMappable::Both));
    var(od, 0x1006, Entry::unsigned32("NMT_CycleLen_U32", Rw, 1000));
    var(od, 0x1008, Entry::visible_string("NMT_ManufactDevName_VS", Const, &id.device_name));
    var(od, 0x1009, Entry::visible_string("NMT_ManufactHwVers_VS", Const, &id.hardware_version));
    var(od, 0x100A, Entry::visible_string("NMT_ManufactSwVers_VS", Const, &id.software_version));
    od.insert(
        0x1018,
        Object::record(
            "NMT_IdentityObject_REC",
            [
                Entry::unsigned32("VendorId_U32", Const, id.vendor_id),
                Entry::unsigned32("ProductCode_U32", Const, id.product_code),
                Entry::unsigned32("RevisionNo_U32", Const, id.revision_number),
                Entry::unsigned32("SerialNo_U32", Const, id.serial_number),
            ],
        ),
    );
    od.insert(
        0x1020,
        Object::record(
            "CFM_VerifyConfiguration_REC",
            [Entry::unsigned32("ConfDate_U32", Rw, 0), Entry::unsigned32("ConfTime_U32", Rw, 0)],
        ),
    );
    od.insert(
        0x1030,
        Object::record(
            "NMT_InterfaceGroup_0h_REC",
            [
                Entry::unsigned16("InterfaceIndex_U16", Ro, 1),
                Entry::visible_string("InterfaceDescription_VSTR", Const, "Interface 1"),
                Entry::unsigned8("InterfaceType_U8", Const, 6),
                Entry::unsigned16("InterfaceMtu_U16", Const, 1518),
                Entry::octet_string("InterfacePhysAddress_OSTR", Const, &id.mac_address),
                Entry::visible_string("InterfaceName_VSTR", Ro, "Interface 1"),
                Entry::unsigned8("InterfaceOperStatus_U8", Ro, 1),
                Entry::unsigned8("InterfaceAdminState_U8", Rw, 1).limits(0, 1),
                Entry::boolean("Valid_BOOL", Rw, true),
            ],
        ),
    );
    od.insert(
        0x1050,
        Object::array("NMT_RelativeLatencyDiff_AU32", 254, Entry::unsigned32("RelativeLatencyDiff", Ro, 0))
            .number_of_entries(Ro, 254),
    );
    var(od, 0x1300, Entry::unsigned32("SDO_SequLayerTimeout_U32", Rw, 15000).low_limit(100));
    for (n, name) in
        [(0u16, "PDO_RxCommParam_00h_REC"), (1, "PDO_RxCommParam_01h_REC"), (2, "PDO_RxCommParam_02h_REC")]
    {
        od.insert(0x1400 + n, pdo_comm(name));
    }
    pdo_mapping(od, 0x1600, "PDO_RxMappParam_00h_AU64");
    pdo_mapping(od, 0x1601, "PDO_RxMappParam_01h_AU64");
    pdo_mapping(od, 0x1602, "PDO_RxMappParam_02h_AU64");
    od.insert(0x1800, pdo_comm("PDO_TxCommParam_00h_REC"));
    pdo_mapping(od, 0x1A00, "PDO_TxMappParam_00h_AU64");
    od.insert(0x1C0B, error_counter("DLL_CNLossSoC_REC"));
    od.insert(0x1C0D, error_counter("DLL_CNLossPReq_REC"));
    od.insert(0x1C0F, error_counter("DLL_CNCRCError_REC"));
    var(od, 0x1C14, Entry::unsigned32("DLL_CNLossOfSocTolerance_U32", Rw, 100_000));
    rw_array(od, 0x1F81, "NMT_NodeAssignment_AU32", 254, 254, Entry::unsigned32("NodeAssignment", Rw, 0));
    var(od, 0x1F82, Entry::unsigned32("NMT_FeatureFlags_U32", Const, id.feature_flags));
    var(od, 0x1F83, Entry::unsigned8("NMT_EPLVersion_U8", Const, 0x20));
    var(od, 0x1F8C, Entry::unsigned8("NMT_CurrNMTState_U8", Ro, NmtState::Initialising.raw()));
    rw_array(
        od,
        0x1F8D,
        "NMT_PResPayloadLimitList_AU16",
        254,
        254,
        Entry::unsigned16("PResPayloadLimit", Rw, 36),
    );
    od.insert(
        0x1F93,
        Object::record(
            "NMT_EPLNodeID_REC",
            [Entry::unsigned8("NodeID_U8", Ro, node_id), Entry::boolean("NodeIDByHW_BOOL", Ro, true)],
        ),
    );
    let max_payload = i128::from(MAX_PAYLOAD);
    od.insert(
        0x1F98,
        Object::record(
            "NMT_CycleTiming_REC",
            [
                Entry::unsigned16("IsochrTxMaxPayload_U16", Const, MAX_PAYLOAD),
                Entry::unsigned16("IsochrRxMaxPayload_U16", Const, MAX_PAYLOAD),
                Entry::unsigned32("PResMaxLatency_U32", Const, 50_000),
                Entry::unsigned16("PReqActPayloadLimit_U16", Rw, 36).limits(36, max_payload),
                Entry::unsigned16("PResActPayloadLimit_U16", Rw, 36).limits(36, max_payload),
                Entry::unsigned32("ASndMaxLatency_U32", Const, 2000),
                Entry::unsigned8("MultiplCycleCnt_U8", Rw, 0),
                Entry::unsigned16("AsyncMTU_U16", Rw, 300).limits(300, 1500),
                Entry::unsigned16("Prescaler_U16", Rw, 2).limits(0, 1000),
                Entry::unsigned8("PResMode_U8", Ro, 0).high_limit(1),
                Entry::unsigned32("PResTimeFirst_U32", Ro, 0),
                Entry::unsigned32("PResTimeSecond_U32", Ro, 0),
                Entry::unsigned32("SyncMNDelayFirst_U32", Ro, 0),
                Entry::unsigned32("SyncMNDelaySecond_U32", Ro, 0),
            ],
        ),
    );
    var(od, 0x1F99, Entry::unsigned32("NMT_CNBasicEthernetTimeout_U32", Rw, 5_000_000));
    rw_array(od, 0x1F9B, "NMT_MultiplCycleAssign_AU8", 254, 254, Entry::unsigned8("CycleNo", Rw, 0));
    var(od, 0x1F9E, Entry::unsigned8("NMT_ResetCmd_U8", Rw, 255));
    // Standardised device profile area (0x6000-): CiA 401.
    let input = |e: Entry| e.pdo(PdoMappable::Tpdo);
    let output = |e: Entry| e.pdo(PdoMappable::Rpdo);
    od.insert(
        0x6000,
        Object::array("DigitalInput_00h_AU8", 4, input(Entry::unsigned8("DigitalInput", Ro, 0))),
    );
    od.insert(
        0x6200,
        Object::array("DigitalOutput_00h_AU8", 4, output(Entry::unsigned8("DigitalOutput", Rw, 0))),
    );
    od.insert(
        0x6400,
        Object::array("AnalogueInput_00h_AI8", 4, input(Entry::integer8("AnalogueInput", Ro, 0))),
    );
    od.insert(
        0x6401,
        Object::array("AnalogueInput_00h_AI16", 2, input(Entry::integer16("AnalogueInput", Ro, 0))),
    );
    od.insert(
        0x6402,
        Object::array("AnalogueInput_00h_AI32", 1, input(Entry::integer32("AnalogueInput", Ro, 0))),
    );
    od.insert(
        0x6410,
        Object::array("AnalogueOutput_00h_AI8", 4, output(Entry::integer8("AnalogueOutput", Rw, 0))),
    );
    od.insert(
        0x6411,
        Object::array("AnalogueOutput_00h_AI16", 2, output(Entry::integer16("AnalogueOutput", Rw, 0))),
    );
    od.insert(
        0x6412,
        Object::array("AnalogueOutput_00h_AI32", 1, output(Entry::integer32("AnalogueOutput", Rw, 0))),
    );
}
