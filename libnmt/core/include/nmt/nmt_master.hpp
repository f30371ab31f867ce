// The CiA 302-2 NMT master as one engine of the shape of nmt/engine.hpp: NMT start-up (§3.1),
// start process boot NMT slave (§3.3), boot NMT slave with error status A..O (§3.4, §3.8), check
// configuration (§3.5), check NMT state (§3.6), start error control, error handler and boot-up
// handler (§4), request NMT and request guarding (1F82h, 1F83h), the NMT inhibit time (102Ah).
//
// It is configured by its own object dictionary, built from a master DCF, the CiA 302 way:
// 1F80h, 1F81h, 1F84h-1F88h, 1F89h, 1F8Ah, 1F90h, 102Ah, 1016h, 1F26h/1F27h, 1F53h/1F54h (values in
// cfg/master_objects.hpp). Objects the file lacks are added with their CiA 302-2 defaults, and its
// own SDO server (default COB-IDs 600h/580h + node-ID) serves them with the §6 value checks, so a
// tool on the bus reads and changes them while it runs. Values are read when a process needs
// them: a change takes effect at the next step that reads it.
//
//   auto master = nmt::NmtMaster::create(master_dcf, node_id, options).value();
//   master.start(now, out);              // power-on: boot-up, then NMT start-up
//   master.on_frame(frame, now, out);    // frames to send and MasterEvents go into `out`
//   master.on_timer(now, out);           // when now >= master.next_deadline()
//
// Choices where CiA 302-2 leaves room (each tested; see the tests of nmt_master):
// - Boot NMT slave begins, after the reset communication of NMT start-up, when the slave's
//   boot-up message arrives or MasterOptions::boot_up_wait after the reset, whichever comes
//   first: a device that is still initialising would not answer the 1000h upload.
// - Any failed 1000h upload (no answer, or an abort) is status B; a failed 1018h upload or a
//   mismatch of sub 1..4 is D, M, N, O. Revision number (N): the major revision (high 16 bits)
//   must be equal and the minor (low 16 bits) at least the expected one (§6.9).
// - Start process boot NMT slave (§3.3): an optional slave is tried again every
//   MasterOptions::retry_interval after any error; a mandatory slave after status B while 1F89h
//   boot time has not elapsed since start-up began (0: without end), and not after other errors.
// - NMT start-up (§3.1 e-f) ends once every slave's start process has its verdict: each
//   mandatory slave booted or ended with a final error, each optional one tried once, and a
//   mandatory slave tried without end after B (1F89h = 0) counts as decided only when another
//   mandatory slave failed. A mandatory slave's final error stops NMT start-up, the start of the
//   network, not the other slaves' processes boot NMT slave (§3.3 runs them asynchronously):
//   every slave is booted to its own end (configured, up to date or its own error status), and
//   only then is StartupHalted reported, naming every mandatory slave that failed (node_id and
//   error: the lowest of them). The BootError with `final` of a mandatory slave is the early
//   sign that start-up will halt. A halted start-up leaves the master pre-operational and
//   starts no slave.
// - No slave is started while NMT start-up runs: with 1F80h bit 1 clear, the start remote node
//   of §3.4 l for a slave that booted during start-up waits for §3.1 h, when every mandatory
//   slave booted and the master entered operational (Table 21: a mandatory device "shall be
//   present prior to network startup"); so the outcome of a halted start-up does not depend on
//   which slave finished first. A slave that boots after start-up ended is started at the end
//   of its boot (§3.4 l).
// - Each SDO transfer of the boot is repeated up to MasterOptions::sdo_retries times when it
//   times out (frame loss), so a lost frame costs one timeout, not a boot.
// - All slaves boot at once, each slave's transfers in order. After the start-up's reset
//   communication no SDO request goes out until every reset slave sent its boot-up (or
//   boot_up_wait passed; with the bit rate known also when no boot-up came for 20 ms: the
//   slaves that booted up start, the others at their boot-up or after boot_up_wait). New
//   transfers are paced to MasterOptions::bus_load_limit when the bit rate is known, the
//   slave furthest behind in its boot first, and limited by a window of transfers in flight
//   that grows by one per window of answers. Unpaced, the window halves on a response timeout
//   (once per loss event); paced, a timeout is a lost frame and costs only its own transfer
//   one sdo_timeout.
// - Check configuration (§3.5): 1F26h/1F27h both 0 mean "do not verify, download". A
//   configuration comes from MasterOptions::configurations, else from the master's own 1F22h
//   sub node-ID (a concise DCF); none at all means there is nothing to download (status OK).
//   Download order: cfg::order_for_download; PDO COB-IDs the configuration does not carry are
//   read from the slave first. Values longer than MasterOptions::block_threshold bytes go by
//   block transfer (segmented when the slave refuses it). Then 1020h sub 1/2 = 1F26h/1F27h (when
//   not 0) and 1010h sub 1 'save' (MasterOptions::save_configuration).
// - Restore (1F81h bit 7): 1011h sub 1F8Ah[node] 'load' (1F8Ah defaults to 1; 0 means no
//   restore), then reset node, then the boot-up is awaited (MasterOptions::reboot_timeout);
//   also when no configuration is stored (the factory defaults are then saved).
// - Software update (1F81h bits 5, 6): 1F51h sub 1 = 0 (stop), 1F51h sub 1 = 3 (clear), 1F50h
//   sub 1 = the image (block transfer, segmented when the slave refuses block), 1F51h sub 1 = 1
//   (start), then 1F52h is read again; a slave still reporting another version is status I.
//   Clear is CiA 302-3's; DSP 302 v3.2.1 §9 gives 1F51h the range 0..2 and real devices built
//   to it refuse 3. A refusal of clear is therefore no failure and the download goes on (the
//   image replaces the stopped program anyway, and a device that cannot take it says so on
//   1F50h): the value-range aborts 0609 0030/0031/0032 (the value 3 is outside the device's
//   range), 0800 0024 (§9: "the action is not possible"), 0800 0000 (general error) and
//   0800 0020 (cannot be transferred or stored), the answers such devices give; the refusal is
//   reported (MasterEvent::ProgramClearRefused, and ProgramUpdate::clear_refused). Any other
//   abort of clear, and any failure of stop, 1F50h or start, is status I naming the step and
//   the abort code in words. The steps have their own response timeouts
//   (MasterOptions::program_control_timeout, program_clear_timeout, program_data_timeout: a
//   device may stop, erase its flash or write a block before it answers); stop, clear and
//   start are repeated sdo_retries times after a timeout as every boot transfer is, the 1F50h
//   download once, from the start of the image.
// - Error handler (§4.2): for a mandatory slave 1F80h bit 6 sends stop all (`000#0200`), else bit
//   4 reset node all (`000#8100`, and NMT start-up runs again), else reset node of that slave
//   (`000#81nn`, Table 12), whose boot-up then restarts its boot (boot-up handler); for an
//   optional slave its boot starts again when 1F81h bit 2 allows (DSP 302 §5.3). The event is
//   reported either way.
// - Boot-up handler (§4.3): a boot-up of an assigned slave (outside its own boot, which awaits
//   boot-ups itself) stops its error control and starts its boot again when 1F81h bit 2 allows;
//   check configuration then reconfigures a replaced device, whose 1020h no longer matches. A
//   boot-up of a node not in 1F81h is reported (CiA 302-2 §3.1: "the responsibility of the
//   application").
// - Execute LSS (MasterOptions::lss, off by default; DSP 302 §4 figure 1 step 3 leaves its
//   content to CiA 305, CiA 302-2 §3.1 c asks for the LSS master services where node-IDs must be
//   set): after the master decision, before the reset communication of all nodes
//   (StartupState::ExecutingLss), the master switches every device to LSS waiting and finds
//   every unconfigured device by Fastscan (nmt/lss_master.hpp's scan). It knows the address of
//   each slave it may assign, so it does not search for those: Fastscan reset (80h, no answer
//   within a scan step: no unconfigured device, the pass ends), then for each slave with an
//   address, in node-ID order (those known to run, 1F82h, last: a look mostly finds the device
//   of a slave that went missing), its four parts confirmed with BitCheck 0 (a device answers only
//   when all 32 bits match; the serial number's match puts it in LSS configuration); a part not
//   answered within a scan step ends that slave (device absent or configured) and the next one
//   starts with a reset, whose silence ends the pass. Only devices still answering the reset
//   after all slaves are searched bit by bit (133 requests each) and reported. A device whose
//   address equals a slave's in all four parts (1F85h-1F88h when all are non-zero, else
//   ExecuteLssOptions::addresses; the revision is a part of the address here, compared exactly,
//   not §6.9's "minor at least") gets that slave's node-ID (configure node-ID, 11h), stores it
//   (17h), and is switched back to waiting, where it starts with it (its boot-up during the scan
//   is not a boot-up handler event: the reset of all nodes follows). A found device that matches
//   no slave is reported (LssUnmatched, with its address) and left unconfigured; a slave whose
//   device is not found is simply missing (its boot ends with status B as without LSS). CiA 305
//   takes LSS addresses to be unique: two devices with one address answer Fastscan as one and
//   are in configuration together; the second answer to configure node-ID tells (LssMaster,
//   nmt/lss_master.hpp), and both are set back to unconfigured (FFh stored) and reported
//   (LssFailed of the slave, naming the address). A device that already
//   has a node-ID is never touched (Fastscan finds only unconfigured ones), and no bit rate is set.
// - ExecuteLssOptions::period: after start-up the active master looks for unconfigured devices
//   (a replaced device) every period: one identify non-configured remote slave (4Ch) and a
//   Fastscan step of silence, and a scan as above (the slaves' addresses confirmed first, so
//   each slave whose device is configured costs a few requests and a step) only when a device
//   answers. The device that
//   gets its node-ID resets its communication, and its boot-up starts its boot (boot-up handler,
//   below): it is configured as any replaced device is. An unconfigured device that matches no
//   slave answers every 4Ch, so it costs a scan each period (reported once).
// - 1F82h (request NMT): a write sends the NMT command through the 102Ah queue, also to the
//   master itself (sub = own node-ID, or 80h: all, the master included). 84h-8Fh need the
//   requester's node-ID, which an SDO write does not carry: aborted 0800 0000 (§6.4). A slave
//   whose state was changed this way is not rebooted automatically (DSP 302 §5.4) until
//   boot_slave() or a 1F82h start. A read gives the state the master knows: heartbeat or
//   guarding reply, else the last command, 01h (missing) after boot error B or a lost
//   heartbeat, 00h when unknown.
//   A request for a node that is not a slave of this master (1F81h bit 0 clear) is aborted
//   0800 0000 (general error). Neither CiA 302-2 nor DSP 302 gives a code (DSP 302 §5.2: the
//   parameters of a slave in the network list "are only valid, if the slave is assigned").
//   §6.4 answers the other refusals of a well-formed request with 0800 0000 (or 0609 0030 for
//   a reserved value); of CiA 301's more specific codes none says this: the sub-index exists
//   (not 0609 0011), the value is a valid request (not 0609 0030), and 0800 0022 (device
//   state) is what this master answers while it is not the NMT master, which must stay
//   distinguishable. 1F83h answers the same for such a node.
// - 1F83h (request guarding): 1 starts guarding with 1F81h's guard time and retry factor (0800
//   0000 when either is 0), 0 stops it; a read gives 1 while the master guards the node.
// - Flying master (1F80h bit 5; CiA 302-2 §3.7, §5.2-§5.5, DSP 302 §5.5 for the COB-IDs and
//   bytes, FlyingMasterCobId below): the master decision (§3.1 b) runs NMT flying master start-up
//   (StartupState::Negotiating): wait 1F90h sub 2, active master detection (73h, answered by
//   71h with priority and node-ID within sub 1); no answer after a power-on: reset communication
//   of all nodes, this device included, and so the start is a warm one; no answer after a
//   reset communication: negotiation (72h, then priority x sub 4 + node-ID x sub 5 ms, restarted
//   by every 72h heard; the first to finish sends 71h and runs NMT start-up). A 71h of a master
//   with a higher or the same priority level (1F90h sub 3 lower or equal; the node-ID only
//   orders the time slots within one negotiation) makes this device an NMT slave
//   (StartupState::Standby) watching that master's heartbeat, so a master of the same level that
//   comes back leaves the running network alone; only a 71h of a lower priority level makes it
//   force a negotiation (76h; §3.7 g/i, §5.4.1), after which it waits 1F90h sub 1 + sub 2 for
//   the reset and detects again. When the worse master wins that negotiation too, this device
//   stands by and forces no more (DSP 302 §5.5.2's hint against a deadlock) until it wins a
//   negotiation itself or yields to a better master; resets in between do not make it forget.
// - The active master answers 73h with 71h and sends 76h every 1F90h sub 6 ms (0: never, §5.5.3)
//   without resetting itself; on a 76h (or another master's 71h, a second active master seen
//   sooner) it resets communication of all nodes and itself, and the negotiation runs again.
// - Error frames shifting the time slots (DSP 302 §5.5.4.4): the slots are this engine's timers,
//   measured against when the other masters' 72h/71h arrived (the event loop hands frames over
//   at their receive stamps, bus_event_loop.hpp "Time"). Error frames short of bus-off cost a
//   retransmission, a few frame times, far below a node time slot; on bus-off the event loop
//   stops sending and stops the engines' clock until the controller is back (bus_event_loop.hpp
//   "Transmit"), so a slot cannot end, nor a 71h be lost, while this device is off the bus. If
//   two masters still overlap, the fallback is §5.5.4.2: the second active master seen makes
//   both reset and negotiate again (above).
// - A standby master takes as the active master's heartbeat consumer time 1016h's entry for that
//   node, else 2 x its own 1017h + 100 ms (the network's masters share one description), and
//   watches nothing when both are 0. A lost heartbeat (§5.5.2) resets communication of all
//   nodes, itself included. Every reset communication of all nodes the flying master sends
//   (power-on, failover, force) follows §3.1 d: when a 1F81h entry has keep-alive set, each other
//   node-ID is reset individually, so keep-alive slaves stay operational across a takeover, and
//   the new master's boot then finds them operational (status L) and checks their
//   configuration (1020h) without a download when it matches.
// - A standby master obeys the NMT commands of the bus addressed to it or to all nodes (a reset
//   restarts flying master start-up, warm); request NMT and request guarding are refused with
//   0800 0022 while it is not the active master.
// - Any device with 1F80h bit 0 set answers NMT master detection (75h) with 74h (§5.1). A
//   self-starting device (Table 16) enters operational by itself; with bit 1 it first asks
//   (75h, 1F91h sub 2 after start-up) and starts all nodes only when no device answered 74h
//   within sub 1, after node-ID x sub 3 ms, and not when another device's start all came first
//   (DSP 302 §5.5.3.1). Without 1F91h in its file it gets §6.14's defaults (100, 500, 15 ms).
// - Other NMT commands from other devices are ignored (there is one NMT master, §5.4).
// - Memory a peer can make the master use is bounded, and a write beyond a bound is refused
//   with 0504 0005 (out of memory; the request is valid, the device has no room for it, which
//   0800 0000 would not say): 1F20h/1F22h/1F23h values by cfg::ConfigManagerLimits (one entry,
//   all nodes), checked at the initiate request when the download indicates its size, else as
//   its data arrives (LocalDictionary::SizeHook), so nothing oversized is buffered; SRDs by
//   MasterOptions::sdo_manager_channels; queued 1F00h requests and 1F82h NMT commands by
//   MasterOptions::sdo_manager_max_queued_requests and max_queued_nmt_requests. An SDO download
//   buffers at most one value per server channel (the default one and the SDO manager's).
// - Configuration manager (DSP 302 §6; MasterOptions::manager): the SDO server serves 1F20h-1F25h
//   from the cfg::ConfigManager with its abort codes (cfg/config_manager.hpp): a tool writes a
//   node's concise DCF into 1F22h sub node-ID (any SDO protocol), a DCF into 1F20h, an EDS into
//   1F23h, and reads them back; an empty 1F22h reads as the count-0 stream (§6.2). 1F25h sub
//   node-ID (80h: every node with a configuration) = 'conf' starts boot NMT slave for that slave
//   with a download even when its 1020h matches ("request re-configuration", §6.4); 0800 0024
//   when the node has no configuration (below), 0800 0000 for a node that is not a slave in
//   1F81h (sub 80h skips those), 0800 0022 while this device is not the active master (a
//   standby flying master). Owner
//   of 1F26h/1F27h: for a node the manager holds anything for (a configuration or a stamp), the
//   manager's values; for other nodes the dictionary's (the master DCF's). SDO reads, SDO writes
//   and check configuration all use that one value; a write goes to the manager, which then holds
//   the node. A configuration comes from the manager when it holds one for the node, else as
//   without a manager; SDO reads of 1F20h-1F22h follow that rule ("stored, else the network"):
//   for a node the manager has no configuration for, 1F22h reads MasterOptions::configurations'
//   concise_dcf(), else the master DCF's own 1F22h, else the count-0 stream, and 1F20h/1F21h its
//   dcf(), so that a tool reads what the master downloads. 1F25h 'conf' configures every slave
//   with a configuration from any of them (sub 80h: all of them).
//   With a store directory (cfg::ConfigManager::persistent()) the master does no disk I/O: an
//   SDO write of 1F20h, 1F22h, 1F23h, 1F26h or 1F27h that changes a stored entry is decided at
//   once (cfg::ConfigManager::stage, its aborts as above) and reported as a
//   MasterEvent::PersistEntry; the driver writes the entry (cfg::ConfigManager::persist, by
//   nmt::MasterHost, nmt/master_host.hpp; off the loop's thread its EntryPersister) and calls
//   entry_persisted() on the loop's thread. Only then does the manager take the value
//   and the SDO confirmation leave (the expedited or last segment's response, or the block end
//   response): a tool that saw the confirmation knows the entry survives a crash. A failed
//   persist aborts the download with 0800 0020 ("data cannot be transferred or stored to the
//   application", CiA 301 §7.2.4.3.17, as the manager answers a store it cannot write) and the
//   manager keeps its old value. A write through dictionary() is persisted the same way when it
//   passes an output of the master (LocalDictionary::write's `out`: its PersistEntry goes there);
//   the manager has the value after entry_persisted().
//   Without a store directory the manager takes the value at once and nothing is reported.
// - SDO manager (DSP 302 §7; MasterOptions::sdo_manager, or a master DCF that has 1F00h): it
//   works only while this device is the active master (active_master() is its own node-ID); a
//   standby flying master ignores the Dynamic SDO Request (6E0h) and refuses 1F00h/1F01h with
//   0800 0022. Every reset communication of all nodes it sends (start-up, takeover) clears its
//   tables: the SRDs and slaves lose their SDO entries with it. Its objects: 1F00h, 1F01h (wo,
//   reads abort 0601 0001), 1F02h (rw), 1F03h-1F06h (ro, 254 rows each, writes abort 0601 0002),
//   and MasterOptions::sdo_manager_channels own server channels 1201h.. (unless the file has
//   them), invalid (bit 31) until an SRD registers on one.
// - 1F02h, the pool: a master DCF without it gets 96 entries 680h..6DFh, identifiers CiA 301's
//   pre-defined connection set neither uses nor restricts. A write is refused with 0800 0022 while
//   any entry is in use (bit 30 is the manager's; §7.2.3 leaves that check to the tool, the
//   manager makes it too), and with 0609 0030 when it sets bit 30 or, without bit 29, bits 28-11.
// - Registration (§7.2.1): a 6E0h data frame of 0 bytes starts a scan of 1F10h over the default
//   SDO, from node-ID 127 down (§7.2.4 guideline 2), skipping this device, registered SRDs and
//   node-IDs whose default SDO a connection holds; each read is tried once and waits
//   MasterOptions::sdo_manager_scan_timeout (no answer: nobody there; 126 silent node-IDs take
//   126 x that time). It stops at the first value with Rq indication set; a 6E0h during a scan
//   makes another scan follow it. The SRD then gets a channel to the manager: a free own server
//   channel (bit 31 of its sub 1 set) and two free pool entries (marked bit 30), written to the
//   SRD's client entry named in 1F10h (sub 3 = manager node-ID, sub 1, sub 2) and to the own
//   channel; the SRD's 1017h is read (error control, below); then 1F10h = index << 16 | Cnxn 1 |
//   Req EC as asked (supported), and once the SRD took that write it is registered and may
//   write 1F00h at once. None free: 1F10h =
//   Cnxn 0 with error 01h. A 1F10h index outside 1280h-12FFh: Cnxn 0 with error 00h. 00000003h
//   (all default SDOs) is granted with 1F10h = 00000004h (Cnxn 2) when no connection holds a
//   default SDO and no other SRD has them, else Cnxn 0 with error 00h. Each registration is a row
//   of 1F03h (client SRD, server this device); a grant of all default SDOs is none (§7.2.2).
// - Error control of a registered SRD (§7.2.1): heartbeat consumption with the master's 1016h
//   entry for it, else 2 x the SRD's 1017h + 100 ms (read at registration), else node guarding
//   with its 1F81h guard time and retry factor, else with MasterOptions::srd_guard_time and life
//   time factor 3. Its loss (or its boot-up: it forgot its entries) releases every connection it
//   held on both sides and de-registers it (SrdLost, then SdoConnectionReleased per row).
// - 1F00h (§7.2.2): the write answers at once (success means started, §7.2.3); the work runs
//   after it, one manager job at a time in arrival order (a scan yields, below). Refused with
//   060A 0023 when the SRD is not registered, the SRD field is not the node-ID the writer's channel
//   belongs to (over the default SDO the field is believed), the slave node-ID is 0 or above 127,
//   names the SRD or this device, or the SRD's client index already carries a connection; 0609 0030
//   when the index is outside 1280h-12FFh. S's default SDO is used when no connection holds it and
//   no SRD has all default SDOs (nothing is written to S; server offset 0, COB-IDs 600h/580h + S);
//   else S's 1201h.. sub 1 are read over the default SDO until one has bit 31 set (that the manager
//   has not given out) and gets sub 3 = SRD, sub 1, sub 2 from two pool entries; then the SRD's
//   client entry (sub 3 = S, sub 1, sub 2) and 1F10h = index << 16 | Cnxn 3 (| Req EC). Failures go
//   into 1F10h with Cnxn 0: 02h no two pool entries free, 03h S has no free server channel (an
//   index S does not have ends the search), 04h S does not answer, 00h S refused a write.
// - Req EC granted: S gets error control if the master does not watch it (1016h entry, else its
//   1F81h guarding, else srd_guard_time guarding); its loss writes 1F11h = 00h << 8 | S on each
//   SRD with EC connected to S (SlaveFailedReported), then clears their client entries.
// - 1F01h (§7.2.3): same checks as 1F00h for the SRD; slave 0 releases everything of the SRD and
//   de-registers it (its channel to the manager last); index 0 every connection of the SRD to S;
//   else the one on that client index (none: success, nothing to do). A release invalidates the
//   SRD's client entry (bit 31 on sub 1 and 2), then S's server entry unless it was the default
//   SDO, then frees the pool entries and the row.
// - The manager's SDO writes are repeated MasterOptions::sdo_retries times on a timeout, like the
//   boot's.
// - A default SDO given out is the SRD's (§7.1: the manager "manages all SDO connections"):
//   the master's own transfers to S (boot, check configuration, downloads, software checks,
//   sdo_upload/sdo_download) wait, in order, while a connection holds S's default SDO or an SRD
//   owns all default SDOs, and go out once it is released (1F01h, SRD lost, reset of all nodes);
//   a boot of S meanwhile stays in its step. The manager's own accesses to S for a connection
//   (the search of S's 1201h.., writing and invalidating them) still use S's default SDO, the only
//   channel §7.1 gives it.
// - Jobs run one at a time, but a scan is a background job: before each of its 1F10h reads, any
//   other job queued meanwhile (1F00h, 1F01h, a release) runs first, so a request waits for at
//   most one scan read, not for the whole scan.
// - A boot-up of S (every reset ends in one, the master's reset node too) releases the
//   connections on S's additional server entries (CiA 301 does not keep 1201h.. over a reset):
//   rows, pool entries and the SRD's client entry (bit 31 on sub 1 and 2, SdoConnectionReleased;
//   nothing is written to S, no 1F11h: its reasons name error control only). A connection on S's
//   default SDO stays (its COB-IDs are fixed).
// - The manager's own server channels 1201h.. are its to open and close: an SDO write to them
//   (or LocalDictionary::write) is refused with 0800 0021 (local control); tools change
//   connections through 1F00h/1F01h (§7.2.3).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/cob_id.hpp"
#include "cfg/concise_dcf.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_dictionary.hpp"
#include "cfg/program_image.hpp"
#include "cfg/result.hpp"
#include "nmt/engine.hpp"
#include "nmt/error_control.hpp"
#include "nmt/frame.hpp"
#include "nmt/local_dictionary.hpp"
#include "nmt/lss_master.hpp"
#include "nmt/master_event.hpp"
#include "nmt/master_options.hpp"
#include "nmt/nmt_slave.hpp"
#include "nmt/sdo_abort.hpp"
#include "nmt/sdo_client.hpp"

namespace cfg {
class ConfigManager;
struct StoreUpdate;
}  // namespace cfg

namespace nmt {

/// The COB-IDs of the flying master protocols (DSP 302 §5.5, Figures 15-19; CiA 302-2 §5.1-5.4).
/// 71h carries 2 bytes: the priority (1F90h sub 3) and the node-ID; the others carry none.
struct FlyingMasterCobId {
  static constexpr std::uint32_t kMasterResponse = 0x71;  ///< active master / winner: "I am master"
  static constexpr std::uint32_t kNegotiationTrigger = 0x72;   ///< start negotiation timers
  static constexpr std::uint32_t kActiveMasterRequest = 0x73;  ///< active NMT master detection
  static constexpr std::uint32_t kCapableResponse = 0x74;      ///< "I am master-capable"
  static constexpr std::uint32_t kCapableRequest = 0x75;       ///< NMT master detection (§5.1)
  static constexpr std::uint32_t kForceNegotiation = 0x76;  ///< force NMT flying master negotiation
};

/// A 1F82h request NMT value as it is written (CiA 302-2 §6.4, Table 28 on download): the NMT
/// service for the node(s) of the sub-index. The 8xh values exclude the NMT master and the
/// requesting device, whose node-ID the request then needs.
enum class NmtRequest : std::uint8_t {
  Stop = 0x04,
  Start = 0x05,
  ResetNode = 0x06,
  ResetCommunication = 0x07,
  EnterPreOperational = 0x7F,
  StopExcluding = 0x84,
  StartExcluding = 0x85,
  ResetNodeExcluding = 0x86,
  ResetCommunicationExcluding = 0x87,
  EnterPreOperationalExcluding = 0x8F,
};

/// The request a written 1F82h byte asks for; nullopt for the values Table 28 reserves (an SDO
/// write of one is aborted with 0609 0030).
constexpr std::optional<NmtRequest> nmt_request_from_byte(std::uint8_t byte) {
  switch (byte & 0x7F) {
    case 0x04:
    case 0x05:
    case 0x06:
    case 0x07:
      return static_cast<NmtRequest>(byte);
    case 0x7F:  // 7Fh, but not FFh
      return byte == 0x7F ? std::optional{NmtRequest::EnterPreOperational} : std::nullopt;
    case 0x0F:  // 8Fh, but not 0Fh
      return byte == 0x8F ? std::optional{NmtRequest::EnterPreOperationalExcluding} : std::nullopt;
    default:
      return std::nullopt;
  }
}
/// Table 28: 84h-8Fh exclude the NMT master and the requesting device.
constexpr bool excludes_master_and_requester(NmtRequest request) {
  return (static_cast<std::uint8_t>(request) & 0x80) != 0;
}
/// The NMT service (CiA 301 §7.2.8.3.1) a request asks for.
constexpr NmtCommand nmt_command_of(NmtRequest request) {
  switch (static_cast<NmtRequest>(static_cast<std::uint8_t>(request) & 0x7F)) {
    case NmtRequest::Stop:
      return NmtCommand::Stop;
    case NmtRequest::Start:
      return NmtCommand::Start;
    case NmtRequest::ResetNode:
      return NmtCommand::ResetNode;
    case NmtRequest::ResetCommunication:
      return NmtCommand::ResetCommunication;
    default:  // 7Fh, 8Fh
      return NmtCommand::EnterPreOperational;
  }
}

/// What the NMT master knows of a node's NMT state, as a 1F82h read gives it (CiA 302-2 §6.4,
/// Table 28 on upload): unknown, missing, or the state the node last showed.
struct KnownState {
  enum class Kind : std::uint8_t { Unknown, Missing, InState };
  Kind kind = Kind::Unknown;
  NmtState state = NmtState::Initialising;  ///< Kind::InState: stopped, operational, pre-op.

  static constexpr KnownState unknown() { return {}; }
  static constexpr KnownState missing() { return {Kind::Missing}; }
  static constexpr KnownState in(NmtState state) {
    // Initialising is no state the master knows a node in (Table 28 has no value for it).
    return state == NmtState::Initialising ? unknown() : KnownState{Kind::InState, state};
  }
  /// Table 28's byte on upload: 00h unknown, 01h missing, 04h/05h/7Fh the state; the
  /// reserved values read as unknown.
  static constexpr KnownState from_byte(std::uint8_t byte) {
    switch (byte) {
      case 0x01:
        return missing();
      case static_cast<std::uint8_t>(NmtState::Stopped):
      case static_cast<std::uint8_t>(NmtState::Operational):
      case static_cast<std::uint8_t>(NmtState::PreOperational):
        return in(static_cast<NmtState>(byte));
      default:
        return unknown();
    }
  }
  /// The state when the master knows it; nullopt when unknown or missing.
  constexpr std::optional<NmtState> nmt_state() const {
    return kind == Kind::InState ? std::optional{state} : std::nullopt;
  }
  constexpr std::uint8_t to_byte() const {
    switch (kind) {
      case Kind::Missing:
        return 0x01;
      case Kind::InState:
        return static_cast<std::uint8_t>(state);
      default:
        return 0x00;
    }
  }
  constexpr bool operator==(const KnownState&) const = default;
};

/// The NMT master. Movable (its state lives behind one pointer), not copyable.
class NmtMaster {
 public:
  using Event = MasterEvent;
  using Output = Outbox<MasterEvent>;
  using TransferId = SdoClient::TransferId;

  /// Builds the master of node `node_id` from its DCF (or EDS): every sub-object becomes a
  /// dictionary entry (LocalDictionary::from_device), and the objects of CiA 302-2 §6 the file
  /// lacks are added with their defaults (1F80h = 1: master, 1F81h..1F88h, 1F8Ah = 1 and 1F82h,
  /// 1F83h for node-IDs 1..127, 102Ah = 0, 1F89h = 0, 1016h with 127 unused entries, 1F26h,
  /// 1F27h, 1F53h, 1F54h, 1F90h = 100, 500, 1, 1500, 10, 4000 + 10 x node-ID ms). Fails with a
  /// message naming the entry when a value does not parse, has reserved bits set, or breaks
  /// §6.13 (1F90h priority above 2, priority time slot not above 127 x device time slot), and
  /// with the error of options.validate() (a timeout that is not positive).
  static cfg::Result<NmtMaster> create(const cfg::DeviceDescription& description,
                                       cfg::NodeId node_id, MasterOptions options = {});
  NmtMaster(NmtMaster&&) noexcept;
  NmtMaster& operator=(NmtMaster&&) noexcept;
  ~NmtMaster();

  // --- engine (nmt/engine.hpp) ---------------------------------------------------------------
  /// Power-on at `now`: the master's boot-up message, then NMT start-up (§3.1): the master
  /// decision and the reset communication go into `out`.
  void start(TimePoint now, Output& out);
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const;

  // --- application -----------------------------------------------------------------------------
  /// §3.1 g with 1F80h bit 2 set: the master enters operational and start-up goes on (start all
  /// nodes per bits 1 and 3). Does nothing in other start-up states.
  void enter_operational(TimePoint now, Output& out);
  /// 1F82h request NMT as the application on the master's own device asks it, for one node or
  /// all nodes (the write to sub-index 80h); `requester` (for the *Excluding requests) is
  /// excluded with the master. Returns the abort an SDO write of the same value gets (None: done).
  SdoAbort request_nmt(NmtTarget target, NmtRequest request, TimePoint now, Output& out,
                       std::optional<cfg::NodeId> requester = std::nullopt);
  /// 1F83h request guarding for one node or all nodes (sub-index 80h), start or stop.
  SdoAbort request_guarding(NmtTarget target, bool start, TimePoint now, Output& out);
  /// Starts the process start process boot NMT slave for `node` (also for a slave left to the
  /// application by 1F81h bit 2: the application asks for it, so it is configured and started;
  /// or held by a request NMT). Could not start (engine.hpp rule 5: an error that says why,
  /// nothing into `out`): `node` is no slave in 1F81h (the status A of §3.4 a, which the
  /// process reports when a slave is taken out of 1F81h while it runs), or a flying master is
  /// not the active master (§3.1 b).
  cfg::Status boot_slave(cfg::NodeId node, TimePoint now, Output& out);
  /// Ends the application's configuration step of `node` (MasterOptions::application_step):
  /// `ok` false ends its boot with status J.
  void configuration_done(cfg::NodeId node, bool ok, TimePoint now, Output& out);
  /// The driver made the entry of MasterEvent::PersistEntry `ticket` durable (`result` ok) or
  /// failed to (`result` says why): the manager takes the value (on success) and the SDO
  /// download that wrote it is confirmed, or aborted with 0800 0020. An unknown ticket is
  /// ignored.
  void entry_persisted(std::uint64_t ticket, const cfg::Status& result, TimePoint now, Output& out);
  /// SDO transfers of the application to a slave, on the master's client for that slave (queued
  /// behind the boot's own transfers). Results come as MasterEvent::SdoFinished. Could not start
  /// (engine.hpp rule 5: the error says why, nothing in `out`): `node` is the master itself, or
  /// SdoClient::check_start refuses (a value over 4 GiB).
  cfg::Result<TransferId> sdo_upload(cfg::NodeId node, std::uint16_t index, std::uint8_t sub,
                                     TimePoint now, Output& out);
  cfg::Result<TransferId> sdo_download(cfg::NodeId node, std::uint16_t index, std::uint8_t sub,
                                       std::vector<std::uint8_t> data, TimePoint now, Output& out);

  // --- observation -----------------------------------------------------------------------------
  cfg::NodeId node_id() const;
  /// The master's own NMT state.
  NmtState state() const;
  StartupState startup_state() const;
  /// The active NMT master as this device knows it: its own node-ID once it won the flying
  /// master negotiation (or without 1F80h bit 5, once start-up began), the winner's while in
  /// standby, nullopt while negotiating or when not a master.
  std::optional<cfg::NodeId> active_master() const;
  /// The state the master knows of `node`, as a 1F82h read gives it (KnownState::to_byte).
  KnownState known_state(cfg::NodeId node) const;
  BootStep boot_step(cfg::NodeId node) const;
  /// The error status of the last finished try of `node`; nullopt after status OK or before.
  std::optional<BootError> last_error(cfg::NodeId node) const;
  /// The dictionary (its values configure the master). Writes through LocalDictionary::write
  /// are checked as SDO writes are; the NMT commands a 1F82h write asks for are queued and due
  /// at once (next_deadline()), so they go out from the next on_timer(). A write that starts
  /// work in the call itself (1F82h for the master itself, 1F25h, 1F20h-1F27h with a store
  /// directory) needs an output of the master to put it in (`out` of LocalDictionary::write, a
  /// NmtMaster::Output the caller then sends and reads): without one it is refused with
  /// 0800 0022 (engine.hpp rule 6: no output kept for a later call).
  const LocalDictionary& dictionary() const;
  LocalDictionary& dictionary();
  /// MasterOptions::manager (nullptr without one): the driver persists a PersistEntry's update
  /// with it (cfg::ConfigManager::persist) before it calls entry_persisted().
  const cfg::ConfigManager* config_manager() const;
  /// The SDO manager's connections, the rows of 1F03h-1F06h in row order (empty without it).
  std::vector<ManagedSdoConnection> sdo_connections() const;
  /// The SRDs the SDO manager registered, by node-ID.
  std::vector<RegisteredSrd> registered_srds() const;

 private:
  struct Impl;
  explicit NmtMaster(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};
static_assert(Engine<NmtMaster>);

}  // namespace nmt
