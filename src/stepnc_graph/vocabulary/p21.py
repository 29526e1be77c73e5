"""The ``p21:`` vocabulary: how EXPRESS and Part 21 structure shows in RDF.

Defined once here as data; ``ontology/p21.ttl`` and the ``P21`` class of
:mod:`stepnc_graph.vocabulary.terms` are generated from it. Kinds: ``annotation`` (on
ontology terms), ``data``/``object`` (on loaded instances), ``class``,
``individual``, ``datatype``.
"""

from __future__ import annotations

from typing import NamedTuple


class Term(NamedTuple):
    name: str
    kind: str
    comment: str


TERMS: tuple[Term, ...] = (
    # annotations on vocabulary terms
    Term("expressName", "annotation", "The name of the declaration, attribute or enumeration item in the EXPRESS schema."),
    Term("expressKind", "annotation", "What the EXPRESS declaration is: ENTITY, DEFINED_TYPE, ENUMERATION or SELECT."),
    Term("expressType", "annotation", "The attribute's type as written in EXPRESS, e.g. 'LIST [2:?] OF manufacturing_feature'."),
    Term("schema", "annotation", "The name of the EXPRESS schema that declares the term."),
    Term("isoPart", "annotation", "The part of ISO 14649 or ISO 10303 the declaring schema belongs to."),
    Term("isoClause", "annotation", "The clause of the source document that describes the term, where known."),
    Term("abstract", "annotation", "True for an ABSTRACT entity: instances must belong to a subtype."),
    Term("supertypeExpression", "annotation", "The entity's SUPERTYPE OF expression as written in EXPRESS."),
    Term("declaredBy", "annotation", "The entity class that declares the attribute."),
    Term("attributeKind", "annotation", "explicit, derived or inverse."),
    Term("position", "annotation", "1-based place of the attribute in the Part 21 record of the declaring entity."),
    Term("optional", "annotation", "True when the attribute is OPTIONAL (Part 21 may write $)."),
    Term("aggregate", "annotation", "The aggregate kind and bounds of the attribute, e.g. 'LIST [2:?]'; nested ones separated by ' OF '."),
    Term("elementType", "annotation", "The class or datatype of the members of an aggregate-valued attribute."),
    Term("derivation", "annotation", "The DERIVE expression of a derived attribute, as EXPRESS source."),
    Term("inverseFor", "annotation", "The forward attribute property an INVERSE attribute inverts."),
    Term("underlyingDatatype", "annotation", "For a defined type: the XSD datatype its values are written with."),
    Term("underlyingType", "annotation", "For a defined type: its underlying type as written in EXPRESS."),
    Term("whereRule", "annotation", "A WHERE rule of the declaration, 'label: expression' in EXPRESS source."),
    Term("uniqueRule", "annotation", "A UNIQUE rule of the entity, 'label: attributes'."),
    Term("redeclaration", "annotation", "An attribute the entity redeclares, as 'SELF\\supertype.attribute : type'."),
    # instance-level structure (used by the Part 21 loader)
    Term("id", "data", "The instance name (#id) the instance has in its Part 21 file, without '#'."),
    Term("line", "data", "The line of the Part 21 file where the instance starts."),
    Term("derivedValue", "object", "An attribute written '*' in Part 21 because a subtype derives it."),
    Term("emptyAggregate", "object", "An attribute whose SET value is the empty set '()' (SETs are otherwise repeated triples)."),
    Term("value", "data", "The literal inside a typed value node, e.g. the 2.5 of LENGTH_MEASURE(2.5)."),
    Term("TypedValue", "class", "A value written with its defined type's name, as Part 21 does inside a SELECT."),
    Term("RawInstance", "class", "An instance kept verbatim because it does not fit the schema; see p21:rawText."),
    Term("rawText", "data", "The Part 21 text of an instance that could not be mapped to the schema."),
    Term("entityName", "data", "The entity name(s) a raw instance was written with, '+'-separated for complex ones."),
    Term("UnreadableInstance", "class", "An instance with a syntax error, kept as its source text (p21:rawText) so "
                                        "nothing of the file is lost; the Part 21 export writes it as a comment."),
    Term("syntaxError", "data", "Why an unreadable instance could not be read, as the reader reported it."),
    Term("repairedText", "data", "The Part 21 text of a raw instance as the lenient reader repaired it (a missing "
                                 "';', a typographic quote); the export writes it, p21:rawText keeps the original."),
    Term("duplicateDefinition", "object", "A later definition of the instance's #id, which was not loaded: a node "
                                          "with its p21:rawText and p21:line; the Part 21 export writes it as a "
                                          "comment."),
    # loaded files (subject: the named graph of one file)
    Term("ExchangeStructure", "class", "A Part 21 file loaded as one named graph; the graph IRI is the subject."),
    Term("unreadableText", "object", "Text of the file that names no instance the reader could read (an instance "
                                     "whose #id is damaged, junk between instances or sections, text after the end "
                                     "marker): a node with its p21:rawText, p21:line and p21:syntaxError; the Part 21 "
                                     "export writes it as a comment."),
    Term("headerText", "data", "The HEADER section of the file, verbatim, so the writer can restore it."),
    Term("repairedHeaderText", "data", "The HEADER section as the lenient reader repaired it; the export writes it, "
                                       "p21:headerText keeps the original."),
    Term("schemaName", "data", "A schema named by the file's FILE_SCHEMA."),
    Term("implementationLevel", "data", "FILE_DESCRIPTION implementation level, e.g. '2;1'."),
    Term("preprocessorVersion", "data", "FILE_NAME preprocessor_version."),
    Term("originatingSystem", "data", "FILE_NAME originating_system."),
    Term("authorization", "data", "FILE_NAME authorization."),
    Term("sha256", "data", "SHA-256 of the file's bytes, hex."),
    Term("byteSize", "data", "Size of the file in bytes."),
    Term("instanceCount", "data", "Instances loaded from the file (mapped and raw)."),
    Term("rawInstanceCount", "data", "Instances kept raw because they do not fit the schema."),
    Term("diagnosticCount", "data", "Diagnostics the load reported."),
    Term("edition", "data", "The edition of ISO 14649 a file was read in (on its graph: 2002, fdis2001), or, on an "
                            "instance, the other edition whose form it has (the writer writes it in that form)."),
    Term("editionChosenBy", "data", "How the file's edition was chosen: option (--edition), header (FILE_SCHEMA or "
                                    "FILE_NAME), content (entity names only one edition has) or default."),
    Term("editionEvidence", "data", "One piece of evidence for or against the file's edition, in words."),
    # edition 3 (ISO 10303-21:2016) structure
    Term("anchorName", "data", "A name the file's ANCHOR section gives the instance, for links from other files."),
    Term("externalReference", "data", "The resource the file's REFERENCE section says defines this instance outside the file."),
    Term("anchorSectionText", "data", "The ANCHOR section of the file, verbatim, so the writer can restore it."),
    Term("referenceSectionText", "data", "The REFERENCE section of the file, verbatim, so the writer can restore it."),
    Term("signatureText", "data", "A SIGNATURE section of the file, verbatim (it signs the original bytes, so the writer does not repeat it)."),
    Term("DataSection", "class", "One DATA section of a file that has several."),
    Term("dataSection", "object", "The DATA section that holds the instance (only in files with several)."),
    Term("sectionIndex", "data", "1-based place of a DATA section in its file."),
    Term("sectionText", "data", "The opening of a DATA section verbatim, e.g. DATA('a',('TURNING_SCHEMA'));."),
    # links to PLM data (subject: a link graph written by `stepnc-graph link`)
    Term("LinkGraph", "class", "A named graph of links from a program's instances to PLM identifiers (owl:sameAs, "
                               "dcterms:identifier), written from one mapping file; the program graph is not changed."),
    Term("linkedProgram", "object", "The program graph (p21:ExchangeStructure) whose instances a link graph links."),
    Term("unset", "individual", "An unset ($) member of an ARRAY with OPTIONAL elements."),
    Term("List", "class", "An RDF collection (rdf:first / rdf:rest) holding a LIST, ARRAY or BAG value, or a nested "
                          "aggregate: the range of such attributes (OWL 2 DL reserves rdf:List). The members' class "
                          "or datatype is the attribute's p21:elementType."),
    Term("logicalUnknown", "datatype", "Datatype of the LOGICAL value UNKNOWN, the only member of its value space: "
                                       "\"UNKNOWN\"^^p21:logicalUnknown. Defined (owl:equivalentClass) as the one "
                                       "string \"UNKNOWN\", so that OWL 2 DL reasoners accept it; a reasoner reads a "
                                       "value of it as that string (OWL 2 DL admits no literal of a defined datatype)."),
)
