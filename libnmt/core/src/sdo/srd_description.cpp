// The device description of an SdoSession that asks the SDO manager for a channel
// (nmt/io/sdo_session.hpp): sans-I/O data, next to the SDO requesting device engine.
#include "nmt/sdo/srd_description.hpp"

namespace nmt {
namespace {

// The session as an SDO requesting device (DSP 302 §7.2.3: 1F10h, 1F11h, a client entry for the
// channel to the manager and one for the connection; CiA 301: 1000h, 1001h, 1018h). Its
// heartbeat (1017h, 200 ms) is what the manager watches while it is registered (§7.2.1).
constexpr std::string_view kSrdDescription = R"([FileInfo]
FileName=cfgmgr_sdo_srd.eds
FileVersion=1
FileRevision=0
EDSVersion=4.0
Description=cfgmgr sdo --via-manager as an SDO requesting device (DSP 302 Section 7)
CreatedBy=canopen-commissioning project

[DeviceInfo]
VendorName=canopen-commissioning project
VendorNumber=0x00000000
ProductName=cfgmgr sdo
ProductNumber=0x00000000
RevisionNumber=0x00000000
BaudRate_10=1
BaudRate_20=1
BaudRate_50=1
BaudRate_125=1
BaudRate_250=1
BaudRate_500=1
BaudRate_800=1
BaudRate_1000=1
SimpleBootUpMaster=0
SimpleBootUpSlave=1
Granularity=0
DynamicChannelsSupported=0
GroupMessaging=0
NrOfRXPDO=0
NrOfTXPDO=0
LSS_Supported=0

[MandatoryObjects]
SupportedObjects=3
1=0x1000
2=0x1001
3=0x1018

[1000]
ParameterName=Device type
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=0x00000000
PDOMapping=0

[1001]
ParameterName=Error register
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=0
PDOMapping=0

[1018]
ParameterName=Identity object
ObjectType=0x9
SubNumber=2

[1018sub0]
ParameterName=Highest sub-index supported
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=1
PDOMapping=0

[1018sub1]
ParameterName=Vendor-ID
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=0x00000000
PDOMapping=0

[OptionalObjects]
SupportedObjects=6
1=0x1017
2=0x1200
3=0x1280
4=0x1281
5=0x1F10
6=0x1F11

[1017]
ParameterName=Producer heartbeat time
ObjectType=0x7
DataType=0x0006
AccessType=rw
DefaultValue=200
PDOMapping=0

[1200]
ParameterName=Server SDO parameter
ObjectType=0x9
SubNumber=3

[1200sub0]
ParameterName=Highest sub-index supported
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=2
PDOMapping=0

[1200sub1]
ParameterName=COB-ID client to server
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=$NODEID+0x600
PDOMapping=0

[1200sub2]
ParameterName=COB-ID server to client
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=$NODEID+0x580
PDOMapping=0

[1280]
ParameterName=Client SDO parameter
ObjectType=0x9
SubNumber=4

[1280sub0]
ParameterName=Highest sub-index supported
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=3
PDOMapping=0

[1280sub1]
ParameterName=COB-ID client to server
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=0x80000000
PDOMapping=0

[1280sub2]
ParameterName=COB-ID server to client
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=0x80000000
PDOMapping=0

[1280sub3]
ParameterName=Node-ID of the SDO server
ObjectType=0x7
DataType=0x0005
AccessType=rw
DefaultValue=0
PDOMapping=0

[1281]
ParameterName=Client SDO parameter
ObjectType=0x9
SubNumber=4

[1281sub0]
ParameterName=Highest sub-index supported
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=3
PDOMapping=0

[1281sub1]
ParameterName=COB-ID client to server
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=0x80000000
PDOMapping=0

[1281sub2]
ParameterName=COB-ID server to client
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=0x80000000
PDOMapping=0

[1281sub3]
ParameterName=Node-ID of the SDO server
ObjectType=0x7
DataType=0x0005
AccessType=rw
DefaultValue=0
PDOMapping=0

[1F10]
ParameterName=Dynamic SDO connection state
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=0x00000000
PDOMapping=0

[1F11]
ParameterName=Slave failed
ObjectType=0x7
DataType=0x0006
AccessType=wo
DefaultValue=0x0000
PDOMapping=0
)";

}  // namespace

std::string_view session_srd_description() {
  return kSrdDescription;
}

}  // namespace nmt
