/*
 * roco bench, part "jade" (services/bench/jade.py): the responder, in JADE's main container.
 *
 * Started by jade.Boot with "-agents NAME:RocoBenchResponder". It prints the line
 * "roco-bench-ready" on standard output once its behaviour is added (the Python side waits for
 * it before it starts the other container), then, in one cyclic behaviour that takes every
 * message waiting in its queue at each wake-up:
 *   - request (fipa-request): answers with an inform carrying the same content (createReply);
 *   - inform in the conversation "stream": counts it and stamps its arrival (System.nanoTime);
 *     informs of any other conversation (the warm-up stream) are taken in and not counted;
 *   - query-ref in the conversation "stream-end": answers with an inform whose content is
 *     "COUNT SPAN_NS", the counted informs and the time from the first to the last, then
 *     starts counting afresh.
 * It writes nothing else on standard output.
 */

import jade.core.Agent;
import jade.core.behaviours.CyclicBehaviour;
import jade.lang.acl.ACLMessage;

public class RocoBenchResponder extends Agent {
    private static final long serialVersionUID = 1L;
    static final String READY = "roco-bench-ready";

    private long count;
    private long firstNs;
    private long lastNs;

    @Override
    protected void setup() {
        addBehaviour(new CyclicBehaviour(this) {
            private static final long serialVersionUID = 1L;

            @Override
            public void action() {
                ACLMessage msg = myAgent.receive();
                if (msg == null) {
                    block();
                    return;
                }
                while (msg != null) {
                    take(msg);
                    msg = myAgent.receive();
                }
            }
        });
        System.out.println(READY);
        System.out.flush();
    }

    private void take(ACLMessage msg) {
        switch (msg.getPerformative()) {
            case ACLMessage.REQUEST: {
                ACLMessage reply = msg.createReply();
                reply.setPerformative(ACLMessage.INFORM);
                reply.setContent(msg.getContent());
                send(reply);
                break;
            }
            case ACLMessage.INFORM: {
                if ("stream".equals(msg.getConversationId())) {
                    long now = System.nanoTime();
                    if (count == 0) {
                        firstNs = now;
                    }
                    lastNs = now;
                    count++;
                }
                break;
            }
            case ACLMessage.QUERY_REF: {
                ACLMessage reply = msg.createReply();
                reply.setPerformative(ACLMessage.INFORM);
                reply.setContent(count + " " + (lastNs - firstNs));
                send(reply);
                count = 0;
                break;
            }
            default:
                break;
        }
    }
}
