// Decodes every message of an LCM log the way lcm-spy does: the type found by its fingerprint
// among the classes on the class path (lcm.spy.LCMTypeDatabase, lcm-spy's own lookup), then each
// message decoded and encoded again to the same bytes. Prints a line per channel and type.
//   java -cp lcm.jar:pneu_lcmtypes.jar DecodeLcmLog.java LOG CHANNEL...
// Exits 1 when a message has no known type, does not decode to the same bytes, or when one of the
// CHANNELs carried no message; 0 otherwise.
import java.io.EOFException;
import java.util.Map;
import java.util.TreeMap;
import lcm.lcm.LCMDataOutputStream;
import lcm.lcm.LCMEncodable;
import lcm.logging.Log;
import lcm.spy.LCMTypeDatabase;

public class DecodeLcmLog {
  public static void main(String[] args) throws Exception {
    LCMTypeDatabase types = new LCMTypeDatabase();
    Map<String, Integer> decoded = new TreeMap<>();
    int failures = 0;
    Log log = new Log(args[0], "r");
    for (;;) {
      Log.Event event;
      try {
        event = log.readNext();
      } catch (EOFException end) {
        break;
      }
      long fingerprint = 0;
      for (int i = 0; i < 8 && i < event.data.length; ++i) fingerprint = (fingerprint << 8) | (event.data[i] & 0xff);
      Class<?> type = types.getClassByFingerprint(fingerprint);
      if (type == null) {
        if (failures++ < 10) System.out.printf("%s: message %d: no type with fingerprint %016x%n", event.channel, event.eventNumber, fingerprint);
        continue;
      }
      try {
        LCMEncodable message = (LCMEncodable) type.getConstructor(byte[].class).newInstance((Object) event.data);
        LCMDataOutputStream out = new LCMDataOutputStream();
        message.encode(out);
        if (!java.util.Arrays.equals(out.toByteArray(), event.data)) throw new Exception("encoded again, the bytes differ");
        decoded.merge(event.channel + " " + type.getName(), 1, Integer::sum);
      } catch (Exception e) {
        if (failures++ < 10) System.out.printf("%s: message %d (%s): %s%n", event.channel, event.eventNumber, type.getName(), e);
      }
    }
    log.close();
    decoded.forEach((channel, n) -> System.out.printf("%s: %d messages decoded%n", channel, n));
    for (int i = 1; i < args.length; ++i) {
      final String channel = args[i];
      if (decoded.keySet().stream().noneMatch(k -> k.startsWith(channel + " "))) {
        System.out.printf("%s: no message%n", channel);
        ++failures;
      }
    }
    System.out.printf("%d failures%n", failures);
    System.exit(failures == 0 ? 0 : 1);
  }
}
