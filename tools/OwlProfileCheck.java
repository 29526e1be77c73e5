/*
 * stepnc-graph: the OWL 2 DL profile check of the shipped vocabulary, with the OWL API
 * (Debian's libowlapi-java). Run as a single-file source program (Java 11 or later):
 *
 *   java -cp <owlapi jars> tools/OwlProfileCheck.java IRI=FILE ...
 *
 * Each argument maps an ontology IRI to the file that holds it (ontology/*.ttl). Imports
 * resolve only through these pairs: an import of any other IRI is left out (reported on
 * standard error), so the check never reads the network. Every ontology is checked with
 * its imports closure, and so is the union of all (one ontology holding every axiom, as a
 * store's vocabulary graph holds every file).
 *
 * Standard output: one line per violation, "ontology IRI <TAB> violation kind <TAB> text";
 * the last line of standard error counts them. Exit status 0 whatever the count (the
 * caller judges), 2 when a file cannot be read.
 */

import java.io.File;
import java.util.ArrayList;
import java.util.LinkedHashMap;
import java.util.List;
import java.util.Map;
import org.semanticweb.owlapi.apibinding.OWLManager;
import org.semanticweb.owlapi.model.IRI;
import org.semanticweb.owlapi.model.MissingImportHandlingStrategy;
import org.semanticweb.owlapi.model.OWLOntology;
import org.semanticweb.owlapi.model.OWLOntologyLoaderConfiguration;
import org.semanticweb.owlapi.model.OWLOntologyManager;
import org.semanticweb.owlapi.profiles.OWL2DLProfile;
import org.semanticweb.owlapi.profiles.OWLProfileViolation;

public class OwlProfileCheck {
    static final String UNION = "urn:x-stepnc-graph:all-ontologies";

    public static void main(String[] args) throws Exception {
        Map<IRI, IRI> files = new LinkedHashMap<>();
        for (String arg : args) {
            int eq = arg.indexOf('=');
            if (eq < 1) {
                System.err.println("expected IRI=FILE, got " + arg);
                System.exit(2);
            }
            File f = new File(arg.substring(eq + 1));
            if (!f.isFile()) {
                System.err.println("no such file: " + f);
                System.exit(2);
            }
            files.put(IRI.create(arg.substring(0, eq)), IRI.create(f.getAbsoluteFile()));
        }
        OWLOntologyManager m = OWLManager.createOWLOntologyManager();
        IRI nowhere = IRI.create(new File("/nonexistent/unmapped-import.ttl"));
        m.getIRIMappers().clear();
        m.getIRIMappers().add(iri -> files.getOrDefault(iri, nowhere));
        m.setOntologyLoaderConfiguration(new OWLOntologyLoaderConfiguration()
            .setMissingImportHandlingStrategy(MissingImportHandlingStrategy.SILENT)
            .setReportStackTraces(false));
        m.addMissingImportListener(e -> System.err.println("import left out: " + e.getImportedOntologyURI()));
        OWLOntology union = m.createOntology(IRI.create(UNION));
        List<OWLOntology> checked = new ArrayList<>();
        for (IRI iri : files.keySet()) {
            OWLOntology o = m.getOntology(iri);
            if (o == null) {
                o = m.loadOntology(iri);
            }
            checked.add(o);
            m.addAxioms(union, o.axioms());
        }
        checked.add(union);
        int count = 0;
        OWL2DLProfile profile = new OWL2DLProfile();
        for (OWLOntology o : checked) {
            String name = o.getOntologyID().getOntologyIRI().map(IRI::toString).orElse("?");
            for (OWLProfileViolation v : profile.checkOntology(o).getViolations()) {
                System.out.println(name + "\t" + v.getClass().getSimpleName() + "\t"
                    + v.toString().replace('\n', ' ').replace('\t', ' '));
                count++;
            }
        }
        System.err.println("OWL 2 DL profile violations: " + count);
    }
}
