/*
 * roco bench, part "jade" (services/bench/jade.py): the initiator, in a peripheral container of
 * its own JVM.
 *
 * Started by jade.Boot with
 *   "-agents NAME:RocoBenchInitiator(RESPONDER,WARMUP,ROUND_TRIPS,MESSAGES,SIZE,TIMEOUT_MS)".
 * In one one-shot behaviour, against the agent RESPONDER (RocoBenchResponder) of the platform:
 *   1. WARMUP + ROUND_TRIPS round trips, one after the other: a request (fipa-request, a new
 *      conversation-id and reply-with each) with SIZE characters of content, then
 *      blockingReceive of the inform in reply to it; the time from just before send() to the
 *      return of blockingReceive (System.nanoTime) is kept for the last ROUND_TRIPS;
 *   2. WARMUP informs in the conversation "warm-up" (the responder does not count them), then
 *      MESSAGES informs in the conversation "stream", sent in a loop;
 *   3. a query-ref in the conversation "stream-end": the responder answers "COUNT SPAN_NS".
 * Then it prints one JSON line on standard output:
 *   {"jade": VERSION, "java": VERSION, "round_trips_ns": [...], "sent": MESSAGES,
 *    "count": COUNT, "span_ns": SPAN_NS, "send_ns": NS}
 * or {"error": "..."} when an answer does not come within TIMEOUT_MS; nothing else on standard
 * output. The process is ended by whoever started it.
 */

import jade.core.AID;
import jade.core.Agent;
import jade.core.behaviours.OneShotBehaviour;
import jade.lang.acl.ACLMessage;
import jade.lang.acl.MessageTemplate;

public class RocoBenchInitiator extends Agent {
    private static final long serialVersionUID = 1L;

    @Override
    protected void setup() {
        final Object[] args = getArguments();
        addBehaviour(new OneShotBehaviour(this) {
            private static final long serialVersionUID = 1L;

            @Override
            public void action() {
                String line;
                try {
                    line = measure(args);
                } catch (RuntimeException e) {
                    line = "{\"error\": " + quoted(e.toString()) + "}";
                }
                System.out.println(line);
                System.out.flush();
            }
        });
    }

    private String measure(Object[] args) {
        if (args == null || args.length != 6) {
            throw new IllegalArgumentException(
                "expected 6 arguments: responder, warm-up, round trips, messages, size, timeout ms");
        }
        AID peer = new AID(String.valueOf(args[0]), AID.ISLOCALNAME);
        int warmup = Integer.parseInt(String.valueOf(args[1]).trim());
        int roundTrips = Integer.parseInt(String.valueOf(args[2]).trim());
        int messages = Integer.parseInt(String.valueOf(args[3]).trim());
        int size = Integer.parseInt(String.valueOf(args[4]).trim());
        long timeoutMs = Long.parseLong(String.valueOf(args[5]).trim());
        StringBuilder body = new StringBuilder(size);
        for (int i = 0; i < size; i++) {
            body.append('x');
        }
        String content = body.toString();

        long[] samples = new long[roundTrips];
        for (int i = 0; i < warmup + roundTrips; i++) {
            ACLMessage request = message(ACLMessage.REQUEST, peer, "rt-" + i, content);
            request.setProtocol("fipa-request");
            request.setReplyWith("rt-" + i);
            MessageTemplate inReply = MessageTemplate.MatchInReplyTo("rt-" + i);
            long t0 = System.nanoTime();
            send(request);
            ACLMessage reply = blockingReceive(inReply, timeoutMs);
            long t1 = System.nanoTime();
            if (reply == null) {
                throw new IllegalStateException("no inform to round trip " + i + " within " + timeoutMs + " ms");
            }
            if (i >= warmup) {
                samples[i - warmup] = t1 - t0;
            }
        }

        for (int i = 0; i < warmup; i++) {
            send(message(ACLMessage.INFORM, peer, "warm-up", content));
        }
        long s0 = System.nanoTime();
        for (int i = 0; i < messages; i++) {
            send(message(ACLMessage.INFORM, peer, "stream", content));
        }
        long sendNs = System.nanoTime() - s0;
        ACLMessage query = message(ACLMessage.QUERY_REF, peer, "stream-end", "count");
        query.setReplyWith("stream-end");
        send(query);
        ACLMessage counted = blockingReceive(MessageTemplate.MatchInReplyTo("stream-end"), timeoutMs);
        if (counted == null) {
            throw new IllegalStateException("no count of the stream within " + timeoutMs + " ms");
        }
        String[] got = counted.getContent().trim().split(" ");

        StringBuilder out = new StringBuilder(64 + 12 * roundTrips);
        out.append("{\"jade\": ").append(quoted(jade.core.Runtime.getVersion()));
        out.append(", \"java\": ").append(quoted(System.getProperty("java.version")));
        out.append(", \"round_trips_ns\": [");
        for (int i = 0; i < roundTrips; i++) {
            out.append(i == 0 ? "" : ",").append(samples[i]);
        }
        out.append("], \"sent\": ").append(messages);
        out.append(", \"count\": ").append(Long.parseLong(got[0]));
        out.append(", \"span_ns\": ").append(Long.parseLong(got[1]));
        out.append(", \"send_ns\": ").append(sendNs).append('}');
        return out.toString();
    }

    private static ACLMessage message(int performative, AID to, String conversation, String content) {
        ACLMessage msg = new ACLMessage(performative);
        msg.addReceiver(to);
        msg.setConversationId(conversation);
        msg.setContent(content);
        return msg;
    }

    /** A JSON string of text: quotes and backslashes escaped, control characters dropped. */
    private static String quoted(String text) {
        StringBuilder out = new StringBuilder("\"");
        for (char c : String.valueOf(text).toCharArray()) {
            if (c == '"' || c == '\\') {
                out.append('\\').append(c);
            } else if (c >= ' ') {
                out.append(c);
            }
        }
        return out.append('"').toString();
    }
}
